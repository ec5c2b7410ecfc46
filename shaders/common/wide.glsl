// The 8-wide BVH traversal that bvh8.glsl and cwbvh.glsl share; each defines, before
// including this file, how a node's children are read:
//   void wide8_keys(uint node, Ray r, vec3 inv, float limit,
//                   out float k0..k7, out uint r0..r7)
// gives each child's entry distance into [tmin, limit] (+inf when missed or empty) and
// reference. Mirrors traverse_wide in src/accel/bvh/wide.rs: front to back, the hit
// children sorted with SORT8 (WIDE_SORT8), the nearest visited and the others pushed
// farthest first (WIDE_PUSH8), so the stack holds 7 x depth + 1 entries (STACK_SIZE).
// Inner nodes are descended in an inner loop and leaves tested after it; every trace
// takes at most TREE_STEPS steps (nodes + primitive tests), beyond which it stops and
// is resumed with the state of bvh.glsl (BVH_RESTORE, common/bvh_leaf.glsl).
#ifndef ARBOR_WIDE8_GLSL
#define ARBOR_WIDE8_GLSL
#define ACCEL_RESUMABLE 1

bool wide8_traverse(Ray r, inout Hit h, bool any_hit) {
    vec3 inv = safe_rcp3(r.dir);
    float e0, e1;
    if (!ray_box(ACCEL_BOX_MIN, ACCEL_BOX_MAX, r.origin, inv, r.tmin, r.tmax, e0, e1)) return false;
    const float INF = uintBitsToFloat(0x7f800000u);
    uint stack[STACK_SIZE];
    uint sp = 0u;
    uint cur = 0u;
    bool found = false;
    STEPS_START;
    BVH_RESTORE;
    while (steps < TREE_STEPS) {
        while ((cur & BVH_LEAF) == 0u && steps < TREE_STEPS) {
            steps += 1u;
            g_nodes += 1u;
            precise float limit = h.t * (1.0 + BVH_T_MARGIN);
            float k0, k1, k2, k3, k4, k5, k6, k7;
            uint r0, r1, r2, r3, r4, r5, r6, r7;
            wide8_keys(cur, r, inv, limit, k0, k1, k2, k3, k4, k5, k6, k7, r0, r1, r2, r3, r4, r5, r6, r7);
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
        uint tested = steps;
        if (bvh_leaf(cur, r, h, any_hit, true, steps)) {
            found = true;
            if (any_hit) return true;
        }
        BVH_LEAF_CUT(tested);
        if (sp == 0u) return found;
        sp -= 1u;
        cur = stack[sp];
    }
    BVH_SUSPEND;
    return found;
}

bool trace_closest(Ray r, inout Hit h) {
    return wide8_traverse(r, h, false);
}

bool trace_any(Ray r) {
    Hit h;
    h.t = r.tmax; h.prim = NO_PRIM; h.u = 0.0; h.v = 0.0;
    return wide8_traverse(r, h, true);
}

#endif
