// Compressed 8-wide BVH traversal (cwbvh). Mirrors Cwbvh::traverse in
// src/accel/bvh/cwbvh.rs, where the layout is documented: 6 texels per node, the grid
// origin and exponents, the eight children's box planes as bytes on that grid, and
// their references (the binary BVH's encoding: bit 31 leaf, first << 3 | count - 1;
// 0xffffffff none).
//
// A child box decodes to p + q * s per plane (q * s is exact, so one rounding, as on
// the CPU) and is tested as a full-precision box; quantisation only enlarges boxes.
// Front to back: the eight boxes are tested against [tmin, best t (1 + 1e-5)], the hit
// children sorted by entry distance with the 19-comparator network SORT8 (shared
// with bvh8.glsl in common/bvh_leaf.glsl), the nearest visited and the others
// pushed, farthest first, as unconditional writes with conditional increments; the stack holds 7 x depth + 1 entries (STACK_SIZE). Inner
// nodes are descended in an inner loop and leaves tested after it; every trace takes at
// most TREE_STEPS steps (nodes + primitive tests), beyond which the pixel is flagged.

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
    float t0, t1_;
    bool hit = ref != BVH_EMPTY && ray_box(lo, hi, r.origin, inv, r.tmin, limit, t0, t1_);
    return hit ? t0 : uintBitsToFloat(0x7f800000u);
}

bool cwbvh_traverse(Ray r, inout Hit h, bool any_hit) {
    vec3 inv = safe_rcp3(r.dir);
    float e0, e1;
    if (!ray_box(ACCEL_BOX_MIN, ACCEL_BOX_MAX, r.origin, inv, r.tmin, r.tmax, e0, e1)) return false;
    const float INF = uintBitsToFloat(0x7f800000u);
    uint stack[STACK_SIZE];
    uint sp = 0u;
    uint cur = 0u;
    bool found = false;
    STEPS_START;
    while (steps < TREE_STEPS) {
        while ((cur & BVH_LEAF) == 0u && steps < TREE_STEPS) {
            steps += 1u;
            g_nodes += 1u;
            uint base = 6u * cur;
            uvec4 t0 = node_texel(base);
            uvec4 t1 = node_texel(base + 1u);
            uvec4 t2 = node_texel(base + 2u);
            uvec4 t3 = node_texel(base + 3u);
            uvec4 ra = node_texel(base + 4u);
            uvec4 rb = node_texel(base + 5u);
            vec3 p = uintBitsToFloat(t0.xyz);
            vec3 s = uintBitsToFloat(uvec3(t0.w & 255u, (t0.w >> 8u) & 255u, (t0.w >> 16u) & 255u) << 23u);
            precise float limit = h.t * (1.0 + BVH_T_MARGIN);
            float k0 = cw_enter(0u, ra.x, p, s, t1, t2, t3, r, inv, limit);
            float k1 = cw_enter(1u, ra.y, p, s, t1, t2, t3, r, inv, limit);
            float k2 = cw_enter(2u, ra.z, p, s, t1, t2, t3, r, inv, limit);
            float k3 = cw_enter(3u, ra.w, p, s, t1, t2, t3, r, inv, limit);
            float k4 = cw_enter(4u, rb.x, p, s, t1, t2, t3, r, inv, limit);
            float k5 = cw_enter(5u, rb.y, p, s, t1, t2, t3, r, inv, limit);
            float k6 = cw_enter(6u, rb.z, p, s, t1, t2, t3, r, inv, limit);
            float k7 = cw_enter(7u, rb.w, p, s, t1, t2, t3, r, inv, limit);
            uint r0 = ra.x, r1 = ra.y, r2 = ra.z, r3 = ra.w;
            uint r4 = rb.x, r5 = rb.y, r6 = rb.z, r7 = rb.w;
            uint n = uint(k0 < INF) + uint(k1 < INF) + uint(k2 < INF) + uint(k3 < INF)
                   + uint(k4 < INF) + uint(k5 < INF) + uint(k6 < INF) + uint(k7 < INF);
            WIDE_SORT8;
            WIDE_PUSH8;
            if (n > 0u) {
                cur = r0;
            } else {
                if (sp == 0u) return found;
                sp -= 1u;
                cur = stack[sp];
            }
        }
        if ((cur & BVH_LEAF) == 0u) break;
        if (bvh_leaf(cur, r, h, any_hit, true, steps)) {
            found = true;
            if (any_hit) return true;
        }
        // A leaf cut short by the step budget must not end the trace as if complete.
        if (steps >= TREE_STEPS) break;
        if (sp == 0u) return found;
        sp -= 1u;
        cur = stack[sp];
    }
    g_overflow = true;
    return found;
}

bool trace_closest(Ray r, inout Hit h) {
    return cwbvh_traverse(r, h, false);
}

bool trace_any(Ray r) {
    Hit h;
    h.t = r.tmax; h.prim = NO_PRIM; h.u = 0.0; h.v = 0.0;
    return cwbvh_traverse(r, h, true);
}
