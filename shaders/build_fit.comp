#version 460
// The radix tree of Karras 2012 over the sorted (code, primitive) pairs, built and
// fitted in one bottom-up climb (the agglomerative order of Apetrei, "Fast and simple
// agglomerative LBVH construction", 2014), with node numbers and topology as
// lbvh::inner_children on the CPU. A key is the code followed by the primitive index,
// so duplicate codes split by index; keys are distinct, so no tie arises below.
//
// Split s (0 <= s < n-1) lies between keys s and s+1. A node covering keys [lo, hi]
// is the child of the neighbouring split whose two keys share the longer prefix:
// split hi (the node is its left child) or split lo-1 (its right child). Karras
// numbers an inner node by the end of its range that touches its parent's split: a
// left child is inner node hi, a right child inner node lo, the root (all keys) node
// 0; leaf j (key j) is node n-1+j.
//
// One thread per key j climbs from leaf j, which it writes first (box, count 1, leaf
// cost, height 0); thread j also zeroes part of the schedule's counters. At a split
// the first thread to arrive leaves the far end of its range in the split's arrival
// word (aux[s].w, NONE since build_morton.comp) and stops; the second takes it, so it
// knows the parent's range, hence both children's and the parent's node numbers, and
// handles the parent: union box, primitive count, cost with collapse
// (treelet::Restructure::new), height (for the passes by height, build_levels.comp),
// child and parent links; then it climbs on. The arrival word is left at 0. Push: n,
// ct, ci. A climb longer than BUILD_MAX_WALK sets BUILD_ERR_WALK.
#define USE_HEADER 1
#define USE_PAIRS 1
#define USE_PRIM_BOUNDS 1
#define USE_NODES 1
#define USE_LEVELS 1
#include "build/common.glsl"

// One subgroup per workgroup (SPEC_FIT_GROUP, set from the device's subgroup size).
layout(local_size_x_id = SPEC_FIT_GROUP) in;

shared uint s_climbing;

// Common-prefix length of keys i and i + 1 (64-bit keys: code, then index).
int delta_next(uint i) {
    uvec2 a = pairs[i];
    uvec2 b = pairs[i + 1u];
    if (a.x != b.x) return 31 - findMSB(a.x ^ b.x);
    return 32 + 31 - findMSB(a.y ^ b.y);
}

// Whether the node covering keys [lo, hi] (not all keys) is its parent's left child.
bool is_left_child(uint lo, uint hi) {
    return lo == 0u || (hi != pc.n - 1u && delta_next(hi) > delta_next(lo - 1u));
}

void main() {
    uint j = group_index() * gl_WorkGroupSize.x + gl_LocalInvocationID.x;
    uint n = pc.n;
    for (uint w = j; w < LV_ARGS; w += n) levels[w] = 0u;
    if (j < n) {
        uint t = n - 1u + j;
        uint prim = pairs[j].y;
        vec4 lo = prim_bounds[2u * prim];
        vec4 hi = prim_bounds[2u * prim + 1u];
        nodes[2u * t] = uvec4(floatBitsToUint(lo.xyz), LEAF_FLAG | prim);
        nodes[2u * t + 1u] = uvec4(floatBitsToUint(hi.xyz), 1u);
        precise float cost = (pc.ci * box_area(lo.xyz, hi.xyz)) * 1.0;
        aux[t] = uvec4(NONE, 1u, floatBitsToUint(cost), 0u);
        levels[lv_height(t)] = 0u;
    }
    bool climbing = j < n && n > 1u;
    uint lo = j;
    uint hi = j;
    bool left = climbing && is_left_child(j, j);
    // Every lane runs the atomic at every step, idle lanes on a spare word: llvmpipe
    // returned wrong old values from an atomic that only some lanes ran. The spare is
    // the lane's own leaf's arrival word (no split uses it; reset below), so idle lanes
    // do not all hit one word, which serialises them on a big GPU; lanes past the last
    // leaf share entry 2n-1.
    uint spare = j < n ? n - 1u + j : 2u * n - 1u;
    bool done = false;
    for (uint g = 0u; g < BUILD_MAX_WALK; ++g) {
        uint s = left ? hi : lo - 1u;
        memoryBarrierBuffer();
        uint other = atomicExchange(aux[climbing ? s : spare].w, left ? lo : hi);
        climbing = climbing && other != NONE;
        if (climbing) {
            memoryBarrierBuffer();
            aux[s].w = 0u;
            if (left) {
                hi = other;
            } else {
                lo = other;
            }
            uint l = lo == s ? n - 1u + s : s;
            uint r = hi == s + 1u ? n + s : s + 1u;
            bool root = lo == 0u && hi == n - 1u;
            left = !root && is_left_child(lo, hi);
            uint p = root ? 0u : (left ? hi : lo);
            vec3 bmin = min(node_min(l), node_min(r));
            vec3 bmax = max(node_max(l), node_max(r));
            uint count = aux[l].y + aux[r].y;
            precise float children = uintBitsToFloat(aux[l].z) + uintBitsToFloat(aux[r].z);
            nodes[2u * p] = uvec4(floatBitsToUint(bmin), l);
            nodes[2u * p + 1u] = uvec4(floatBitsToUint(bmax), r);
            aux[p].y = count;
            aux[p].z = floatBitsToUint(node_cost(bmin, bmax, count, children));
            aux[l].x = p;
            aux[r].x = p;
            if (root) aux[p].x = NONE;
            levels[lv_height(p)] = 1u + max(levels[lv_height(l)], levels[lv_height(r)]);
            memoryBarrierBuffer();
            climbing = !root;
        }
        if (gl_LocalInvocationID.x == 0u) s_climbing = 0u;
        barrier();
        if (climbing) atomicAdd(s_climbing, 1u);
        barrier();
        done = s_climbing == 0u;
        barrier();
        if (done) break;
    }
    if (j < n) aux[spare].w = 0u;
    if (!done && gl_LocalInvocationID.x == 0u) atomicOr(hdr[BUILD_HDR_ERRORS], BUILD_ERR_WALK);
}

