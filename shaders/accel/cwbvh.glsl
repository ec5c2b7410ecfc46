// Compressed 8-wide BVH (cwbvh): how a node's children are read, for the shared
// traversal of common/wide.glsl. Layout documented in src/accel/bvh/cwbvh.rs: 6 texels
// per node, the grid origin and exponents, the eight children's box planes as bytes on
// that grid, and their references (the binary BVH's encoding: bit 31 leaf,
// first << BVH_LEAF_COUNT_BITS | count - 1; 0xffffffff none).
//
// A child box decodes to p + q * s per plane (q * s is exact, so one rounding, as on
// the CPU) and is tested as a full-precision box; quantisation only enlarges boxes.

#include "common/bvh_leaf.glsl"

// Byte k (0..7) of the pair of words (lo: children 0..3, hi: 4..7), as a float.
float cw_q(uint lo, uint hi, uint k) {
    return float(((k < 4u ? lo : hi) >> (8u * (k & 3u))) & 255u);
}

// Entry distance of child k of the node whose texels 0..3 are t0..t3 (p and s decoded),
// +inf on a miss or an empty slot.
float cw_enter(uint k, uint ref, vec3 p, vec3 s, uvec4 t1, uvec4 t2, uvec4 t3, Ray r, vec3 inv, float limit) {
    vec3 lo = p + vec3(cw_q(t1.x, t1.y, k), cw_q(t1.z, t1.w, k), cw_q(t2.x, t2.y, k)) * s;
    vec3 hi = p + vec3(cw_q(t2.z, t2.w, k), cw_q(t3.x, t3.y, k), cw_q(t3.z, t3.w, k)) * s;
    return wide_enter(ref, lo, hi, r, inv, limit);
}

void wide_keys(uint node, Ray r, vec3 inv, float limit,
               out float k0, out float k1, out float k2, out float k3,
               out float k4, out float k5, out float k6, out float k7,
               out uint r0, out uint r1, out uint r2, out uint r3,
               out uint r4, out uint r5, out uint r6, out uint r7) {
    uint base = 6u * node;
    uvec4 t0 = node_texel(base);
    uvec4 t1 = node_texel(base + 1u);
    uvec4 t2 = node_texel(base + 2u);
    uvec4 t3 = node_texel(base + 3u);
    uvec4 ra = node_texel(base + 4u);
    uvec4 rb = node_texel(base + 5u);
    vec3 p = uintBitsToFloat(t0.xyz);
    vec3 s = uintBitsToFloat(uvec3(t0.w & 255u, (t0.w >> 8u) & 255u, (t0.w >> 16u) & 255u) << 23u);
    r0 = ra.x; r1 = ra.y; r2 = ra.z; r3 = ra.w;
    r4 = rb.x; r5 = rb.y; r6 = rb.z; r7 = rb.w;
    k0 = cw_enter(0u, r0, p, s, t1, t2, t3, r, inv, limit);
    k1 = cw_enter(1u, r1, p, s, t1, t2, t3, r, inv, limit);
    k2 = cw_enter(2u, r2, p, s, t1, t2, t3, r, inv, limit);
    k3 = cw_enter(3u, r3, p, s, t1, t2, t3, r, inv, limit);
    k4 = cw_enter(4u, r4, p, s, t1, t2, t3, r, inv, limit);
    k5 = cw_enter(5u, r5, p, s, t1, t2, t3, r, inv, limit);
    k6 = cw_enter(6u, r6, p, s, t1, t2, t3, r, inv, limit);
    k7 = cw_enter(7u, r7, p, s, t1, t2, t3, r, inv, limit);
}

#define WIDE_WIDTH 8
#include "common/wide.glsl"
