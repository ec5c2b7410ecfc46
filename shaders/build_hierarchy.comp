#version 460
// The binary radix tree of Karras 2012 over the sorted (code, primitive) pairs, as
// lbvh::inner_children on the CPU: a key is the code followed by the primitive index,
// so duplicate codes split by index. Thread t < n-1 makes inner node t; thread
// n-1+j makes leaf j (box, count 1, leaf cost). Push: n (>= 1), ct, ci.
#define USE_PAIRS 1
#define USE_PRIM_BOUNDS 1
#define USE_NODES 1
#include "build/common.glsl"

layout(local_size_x = BUILD_GROUP) in;

// Common-prefix length of keys i and j (64-bit keys: code, then index); -1 outside.
int delta(int i, int j) {
    if (j < 0 || j >= int(pc.n)) return -1;
    uvec2 a = pairs[i];
    uvec2 b = pairs[j];
    if (a.x != b.x) return 31 - findMSB(a.x ^ b.x);
    return 32 + 31 - findMSB(a.y ^ b.y);
}

void main() {
    uint t = group_index() * BUILD_GROUP + gl_LocalInvocationID.x;
    uint n = pc.n;
    if (t >= 2u * n - 1u) return;
    if (t >= n - 1u) {
        uint j = t - (n - 1u);
        uint prim = pairs[j].y;
        vec4 lo = prim_bounds[2u * prim];
        vec4 hi = prim_bounds[2u * prim + 1u];
        nodes[2u * t] = uvec4(floatBitsToUint(lo.xyz), LEAF_FLAG | prim);
        nodes[2u * t + 1u] = uvec4(floatBitsToUint(hi.xyz), 1u);
        precise float cost = (pc.ci * box_area(lo.xyz, hi.xyz)) * 1.0;
        aux[t].y = 1u;
        aux[t].z = floatBitsToUint(cost);
        aux[t].w = 0u;
        if (n == 1u) aux[t].x = NONE;
        return;
    }
    int i = int(t);
    int d = delta(i, i + 1) - delta(i, i - 1) >= 0 ? 1 : -1;
    int dmin = delta(i, i - d);
    int lmax = 2;
    for (uint g = 0u; g < 64u && delta(i, i + lmax * d) > dmin; ++g) lmax *= 2;
    int l = 0;
    for (int s = lmax / 2; s >= 1; s /= 2) {
        if (delta(i, i + (l + s) * d) > dmin) l += s;
    }
    int j = i + l * d;
    int dnode = delta(i, j);
    int s = 0;
    int step = l;
    for (uint g = 0u; g < 64u; ++g) {
        step = (step + 1) / 2;
        if (delta(i, i + (s + step) * d) > dnode) s += step;
        if (step <= 1) break;
    }
    int gamma = i + s * d + min(d, 0);
    int leaf0 = int(n) - 1;
    uint left = uint(min(i, j) == gamma ? leaf0 + gamma : gamma);
    uint right = uint(max(i, j) == gamma + 1 ? leaf0 + gamma + 1 : gamma + 1);
    nodes[2u * t].w = left;
    nodes[2u * t + 1u].w = right;
    aux[left].x = t;
    aux[right].x = t;
    aux[t].w = 0u;
    if (t == 0u) aux[0].x = NONE;
}
