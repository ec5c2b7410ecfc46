// The W-wide BVH traversal (W = WIDE_WIDTH, 4 or 8) that bvh4.glsl, bvh8.glsl and
// cwbvh.glsl share; each defines WIDE_WIDTH and, before including this file, how a
// node's children are read:
//   void wide_keys(uint node, Ray r, vec3 inv, float limit,
//                  out float k0..k{W-1}, out uint r0..r{W-1})
// gives each child's entry distance into [tmin, limit] (+inf when missed or empty,
// wide_enter) and reference. Mirrors traverse_wide in src/accel/bvh/wide.rs: front to
// back, the hit children sorted with SORT4 / SORT8 (WIDE_SORT), the nearest visited
// and the others pushed farthest first (WIDE_PUSH), so the stack holds
// (W - 1) x depth + 1 entries (STACK_SIZE, set at build time). Inner nodes are
// descended in an inner loop and leaves tested after it ("while-while"); every trace
// takes at most TREE_STEPS steps (nodes + primitive tests), beyond which it stops and
// is resumed with the state of bvh.glsl (BVH_RESTORE, common/bvh_leaf.glsl).
#ifndef ARBOR_WIDE_GLSL
#define ARBOR_WIDE_GLSL
#define ACCEL_RESUMABLE 1

// The width's steps, on the loop's locals: WIDE_KEYS declares keys k0.. (entry
// distance, +inf for a child not entered) and references r0.. and reads node cur;
// WIDE_ENTERED counts the children entered (n); WIDE_SORT is SORT4 / SORT8 of
// src/accel/bvh/wide.rs, comparator for comparator; WIDE_PUSH pushes the references
// but the first, last first, as unconditional writes with conditional increments (the
// entered ones, farthest first), leaving r0 the nearest.
#if WIDE_WIDTH == 4
#define WIDE_KEYS \
    float k0, k1, k2, k3; \
    uint r0, r1, r2, r3; \
    wide_keys(cur, r, inv, limit, k0, k1, k2, k3, r0, r1, r2, r3)
#define WIDE_ENTERED (uint(k0 < INF) + uint(k1 < INF) + uint(k2 < INF) + uint(k3 < INF))
#define WIDE_SORT \
    wide_swap(k0, r0, k1, r1); wide_swap(k2, r2, k3, r3); \
    wide_swap(k0, r0, k2, r2); wide_swap(k1, r1, k3, r3); \
    wide_swap(k1, r1, k2, r2)
#define WIDE_PUSH \
    stack[sp] = r3; sp += n > 3u ? 1u : 0u; \
    stack[sp] = r2; sp += n > 2u ? 1u : 0u; \
    stack[sp] = r1; sp += n > 1u ? 1u : 0u
#elif WIDE_WIDTH == 8
#define WIDE_KEYS \
    float k0, k1, k2, k3, k4, k5, k6, k7; \
    uint r0, r1, r2, r3, r4, r5, r6, r7; \
    wide_keys(cur, r, inv, limit, k0, k1, k2, k3, k4, k5, k6, k7, r0, r1, r2, r3, r4, r5, r6, r7)
#define WIDE_ENTERED \
    (uint(k0 < INF) + uint(k1 < INF) + uint(k2 < INF) + uint(k3 < INF) \
     + uint(k4 < INF) + uint(k5 < INF) + uint(k6 < INF) + uint(k7 < INF))
#define WIDE_SORT \
    wide_swap(k0, r0, k2, r2); wide_swap(k1, r1, k3, r3); wide_swap(k4, r4, k6, r6); wide_swap(k5, r5, k7, r7); \
    wide_swap(k0, r0, k4, r4); wide_swap(k1, r1, k5, r5); wide_swap(k2, r2, k6, r6); wide_swap(k3, r3, k7, r7); \
    wide_swap(k0, r0, k1, r1); wide_swap(k2, r2, k3, r3); wide_swap(k4, r4, k5, r5); wide_swap(k6, r6, k7, r7); \
    wide_swap(k2, r2, k4, r4); wide_swap(k3, r3, k5, r5); \
    wide_swap(k1, r1, k4, r4); wide_swap(k3, r3, k6, r6); \
    wide_swap(k1, r1, k2, r2); wide_swap(k3, r3, k4, r4); wide_swap(k5, r5, k6, r6)
#define WIDE_PUSH \
    stack[sp] = r7; sp += n > 7u ? 1u : 0u; \
    stack[sp] = r6; sp += n > 6u ? 1u : 0u; \
    stack[sp] = r5; sp += n > 5u ? 1u : 0u; \
    stack[sp] = r4; sp += n > 4u ? 1u : 0u; \
    stack[sp] = r3; sp += n > 3u ? 1u : 0u; \
    stack[sp] = r2; sp += n > 2u ? 1u : 0u; \
    stack[sp] = r1; sp += n > 1u ? 1u : 0u
#else
#error WIDE_WIDTH must be 4 or 8
#endif

bool wide_traverse(Ray r, inout Hit h, bool any_hit) {
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
            WIDE_KEYS;
            uint n = WIDE_ENTERED;
            WIDE_SORT;
            WIDE_PUSH;
            if (n > 0u) {
                cur = r0;
            } else {
                if (sp == 0u) return found;
                sp -= 1u;
                cur = stack[sp];
            }
        }
        if ((cur & BVH_LEAF) == 0u) break;
        BVH_LEAF_VISIT
    }
    BVH_SUSPEND;
    return found;
}

bool accel_closest(Ray r, inout Hit h) {
    return wide_traverse(r, h, false);
}

bool accel_any(Ray r) {
    Hit h;
    h.t = r.tmax; h.prim = NO_PRIM; h.u = 0.0; h.v = 0.0;
    return wide_traverse(r, h, true);
}

#endif
