// 8-wide BVH traversal (bvh8). Mirrors WideBvh::<8>::traverse in src/accel/bvh/wide.rs,
// where the layout is documented: 14 texels per node, the eight children's boxes as
// structure of arrays (min x, min y, min z, max x, max y, max z; two texels each,
// children 0..3 then 4..7) and their references (the binary BVH's encoding).
//
// Front to back as bvh4.glsl, with eight children: the boxes tested against [tmin,
// best t (1 + 1e-5)], the hit children sorted with the 19-comparator network SORT8
// (common/bvh_leaf.glsl, shared with cwbvh.glsl), the nearest visited and the others
// pushed farthest first; the stack holds 7 x depth + 1 entries (STACK_SIZE). Every
// trace takes at most TREE_STEPS steps, beyond which the pixel is flagged.

#include "common/bvh_leaf.glsl"

// Entry distance of a child box, +inf on a miss or an empty slot.
float bvh8_enter(uint ref, vec3 lo, vec3 hi, Ray r, vec3 inv, float limit) {
    float t0, t1;
    bool hit = ref != BVH_EMPTY && ray_box(lo, hi, r.origin, inv, r.tmin, limit, t0, t1);
    return hit ? t0 : uintBitsToFloat(0x7f800000u);
}

bool bvh8_traverse(Ray r, inout Hit h, bool any_hit) {
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
            uint base = 14u * cur;
            vec4 lxa = uintBitsToFloat(node_texel(base)), lxb = uintBitsToFloat(node_texel(base + 1u));
            vec4 lya = uintBitsToFloat(node_texel(base + 2u)), lyb = uintBitsToFloat(node_texel(base + 3u));
            vec4 lza = uintBitsToFloat(node_texel(base + 4u)), lzb = uintBitsToFloat(node_texel(base + 5u));
            vec4 hxa = uintBitsToFloat(node_texel(base + 6u)), hxb = uintBitsToFloat(node_texel(base + 7u));
            vec4 hya = uintBitsToFloat(node_texel(base + 8u)), hyb = uintBitsToFloat(node_texel(base + 9u));
            vec4 hza = uintBitsToFloat(node_texel(base + 10u)), hzb = uintBitsToFloat(node_texel(base + 11u));
            uvec4 ra = node_texel(base + 12u);
            uvec4 rb = node_texel(base + 13u);
            precise float limit = h.t * (1.0 + BVH_T_MARGIN);
            float k0 = bvh8_enter(ra.x, vec3(lxa.x, lya.x, lza.x), vec3(hxa.x, hya.x, hza.x), r, inv, limit);
            float k1 = bvh8_enter(ra.y, vec3(lxa.y, lya.y, lza.y), vec3(hxa.y, hya.y, hza.y), r, inv, limit);
            float k2 = bvh8_enter(ra.z, vec3(lxa.z, lya.z, lza.z), vec3(hxa.z, hya.z, hza.z), r, inv, limit);
            float k3 = bvh8_enter(ra.w, vec3(lxa.w, lya.w, lza.w), vec3(hxa.w, hya.w, hza.w), r, inv, limit);
            float k4 = bvh8_enter(rb.x, vec3(lxb.x, lyb.x, lzb.x), vec3(hxb.x, hyb.x, hzb.x), r, inv, limit);
            float k5 = bvh8_enter(rb.y, vec3(lxb.y, lyb.y, lzb.y), vec3(hxb.y, hyb.y, hzb.y), r, inv, limit);
            float k6 = bvh8_enter(rb.z, vec3(lxb.z, lyb.z, lzb.z), vec3(hxb.z, hyb.z, hzb.z), r, inv, limit);
            float k7 = bvh8_enter(rb.w, vec3(lxb.w, lyb.w, lzb.w), vec3(hxb.w, hyb.w, hzb.w), r, inv, limit);
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
    return bvh8_traverse(r, h, false);
}

bool trace_any(Ray r) {
    Hit h;
    h.t = r.tmax; h.prim = NO_PRIM; h.u = 0.0; h.v = 0.0;
    return bvh8_traverse(r, h, true);
}
