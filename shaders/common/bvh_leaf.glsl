// What the BVH kernels (bvh.glsl with its single-ray and packet traversals, bvh4.glsl,
// bvh8.glsl, cwbvh.glsl) share: the child-reference encoding of src/accel/bvh/mod.rs,
// the test of one leaf, and the wide kernels' child ordering.
#ifndef ARBOR_BVH_LEAF_GLSL
#define ARBOR_BVH_LEAF_GLSL

#include "common/accel_texels.glsl"

const uint BVH_LEAF = BVH_LEAF_REF;
const uint BVH_EMPTY = BVH_EMPTY_REF;
const float BVH_T_MARGIN = 1e-5;

// Tests the primitives of leaf reference `ref` (first << 3 | count - 1), each a step of
// the trace's budget, and says whether one was hit. With `first_hit`, stops at the
// first hit. `testing` false counts the steps but tests nothing (a packet lane riding
// along), so that every lane takes the same steps.
bool bvh_leaf(uint ref, Ray r, inout Hit h, bool first_hit, bool testing, inout uint steps) {
    uint first = (ref & ~BVH_LEAF) >> 3u;
    uint count = (ref & 7u) + 1u;
    bool found = false;
    for (uint k = 0u; k < count && steps < TREE_STEPS; k++) {
        steps += 1u;
        if (testing && intersect_prim(accel_index(first + k), r, h)) {
            found = true;
            if (first_hit) testing = false;
        }
    }
    return found;
}

// The part of leaf reference `ref` after its first `tested` primitives (tested < count).
uint bvh_leaf_rest(uint ref, uint tested) {
    uint first = (ref & ~BVH_LEAF) >> 3u;
    return BVH_LEAF | ((first + tested) << 3u) | ((ref & 7u) - tested);
}

// Resuming the BVH kernels' traversals (common/resume.glsl), on their locals cur, sp,
// found and stack: words 0 the next reference, 1 sp, 2 found, the stack from
// RESUME_LEVEL_WORDS. BVH_LEAF_CUT(tested): after testing leaf cur from step count
// `tested`, a leaf the step budget cut short leaves the loop with the rest of it in cur.
#define BVH_RESTORE \
    if (RESUME_PASS && g_resuming) { \
        g_resuming = false; \
        cur = rs_get(0u); \
        sp = rs_get(1u); \
        found = rs_get(2u) != 0u; \
        for (uint q = 0u; q < sp; q++) stack[q] = rs_get(RESUME_LEVEL_WORDS + q); \
    }
#define BVH_LEAF_CUT(tested) \
    tested = steps - tested; \
    if (tested <= (cur & 7u)) { \
        cur = bvh_leaf_rest(cur, tested); \
        break; \
    }
#define BVH_SUSPEND \
    if (trace_suspend()) { \
        rs_put(0u, cur); \
        rs_put(1u, sp); \
        rs_put(2u, uint(found)); \
        for (uint q = 0u; q < sp; q++) rs_put(RESUME_LEVEL_WORDS + q, stack[q]); \
    }

// Entry distance of a wide node's child box [lo, hi] into [tmin, limit], +inf on a miss
// or an empty slot (reference BVH_EMPTY).
float wide_enter(uint ref, vec3 lo, vec3 hi, Ray r, vec3 inv, float limit) {
    float t0, t1;
    bool hit = ref != BVH_EMPTY && ray_box(lo, hi, r.origin, inv, r.tmin, limit, t0, t1);
    return hit ? t0 : uintBitsToFloat(0x7f800000u);
}

// Orders (ka, ra) before (kb, rb) when kb < ka: one comparator of a sorting network.
void wide_swap(inout float ka, inout uint ra, inout float kb, inout uint rb) {
    bool s = kb < ka;
    float k = ka;
    uint r = ra;
    ka = s ? kb : ka;
    ra = s ? rb : ra;
    kb = s ? k : kb;
    rb = s ? r : rb;
}

// The 8-wide kernels' child order and pushes, on their locals: keys k0..k7 (entry
// distance, +inf for a child not entered), references r0..r7, n children entered,
// the stack and sp. WIDE_SORT8 is SORT8 of src/accel/bvh/wide.rs, comparator for
// comparator; WIDE_PUSH8 pushes r7..r1 as unconditional writes with conditional
// increments (the entered ones, farthest first), leaving r0 the nearest.
#define WIDE_SORT8 \
    wide_swap(k0, r0, k2, r2); wide_swap(k1, r1, k3, r3); wide_swap(k4, r4, k6, r6); wide_swap(k5, r5, k7, r7); \
    wide_swap(k0, r0, k4, r4); wide_swap(k1, r1, k5, r5); wide_swap(k2, r2, k6, r6); wide_swap(k3, r3, k7, r7); \
    wide_swap(k0, r0, k1, r1); wide_swap(k2, r2, k3, r3); wide_swap(k4, r4, k5, r5); wide_swap(k6, r6, k7, r7); \
    wide_swap(k2, r2, k4, r4); wide_swap(k3, r3, k5, r5); \
    wide_swap(k1, r1, k4, r4); wide_swap(k3, r3, k6, r6); \
    wide_swap(k1, r1, k2, r2); wide_swap(k3, r3, k4, r4); wide_swap(k5, r5, k6, r6)
#define WIDE_PUSH8 \
    stack[sp] = r7; sp += n > 7u ? 1u : 0u; \
    stack[sp] = r6; sp += n > 6u ? 1u : 0u; \
    stack[sp] = r5; sp += n > 5u ? 1u : 0u; \
    stack[sp] = r4; sp += n > 4u ? 1u : 0u; \
    stack[sp] = r3; sp += n > 3u ? 1u : 0u; \
    stack[sp] = r2; sp += n > 2u ? 1u : 0u; \
    stack[sp] = r1; sp += n > 1u ? 1u : 0u

#endif
