// What the BVH kernels (bvh.glsl with its single-ray and packet traversals, the wide
// ones of common/wide.glsl, the top level of common/instances.glsl) share: the
// child-reference encoding of src/accel/bvh/mod.rs, the binary node step, the test of
// one leaf, and the wide kernels' child boxes and comparator.
#ifndef ARBOR_BVH_LEAF_GLSL
#define ARBOR_BVH_LEAF_GLSL

#include "common/accel_texels.glsl"

const uint BVH_LEAF = BVH_LEAF_REF;
const uint BVH_EMPTY = BVH_EMPTY_REF;
const float BVH_T_MARGIN = 1e-5;

// A leaf reference's fields (src/gpu/bindings.rs, BVH_LEAF_COUNT_BITS, with a worked
// example): BVH_LEAF | first << BVH_LEAF_COUNT_BITS | count - 1.
uint bvh_leaf_first(uint ref) { return (ref & ~BVH_LEAF) >> BVH_LEAF_COUNT_BITS; }
uint bvh_leaf_count(uint ref) { return (ref & BVH_LEAF_COUNT_MASK) + 1u; }

// Tests the primitives of leaf reference `ref`, each a step of the trace's budget, and
// says whether one was hit. With `first_hit`, stops at the first hit. `testing` false
// counts the steps but tests nothing (a packet lane riding along), so that every lane
// takes the same steps.
bool bvh_leaf(uint ref, Ray r, inout Hit h, bool first_hit, bool testing, inout uint steps) {
    uint first = bvh_leaf_first(ref);
    uint count = bvh_leaf_count(ref);
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
    uint first = bvh_leaf_first(ref);
    return BVH_LEAF | ((first + tested) << BVH_LEAF_COUNT_BITS) | ((ref & BVH_LEAF_COUNT_MASK) - tested);
}

// One inner node of the binary BVH on a traversal's locals r, inv, h, cur, stack, sp
// and found: the node's four texels (src/accel/bvh/mod.rs) are `fetch(at)` ..
// `fetch(at + 3u)`; both child boxes are tested against [tmin, best t (1 + 1e-5)], the
// nearer child entered becomes cur and the other is pushed; with neither entered, cur
// is popped, and the traversal returns `found` when the stack is empty.
#define BVH_NODE_STEP(fetch, at) \
    uvec4 a = fetch(at); \
    uvec4 b = fetch((at) + 1u); \
    uvec4 c = fetch((at) + 2u); \
    uvec4 d = fetch((at) + 3u); \
    uint lref = a.w; \
    uint rref = b.w; \
    precise float limit = h.t * (1.0 + BVH_T_MARGIN); \
    float l0, l1, r0, r1; \
    bool hl = lref != BVH_EMPTY \
        && ray_box(uintBitsToFloat(a.xyz), uintBitsToFloat(b.xyz), r.origin, inv, r.tmin, limit, l0, l1); \
    bool hr = rref != BVH_EMPTY \
        && ray_box(uintBitsToFloat(c.xyz), uintBitsToFloat(d.xyz), r.origin, inv, r.tmin, limit, r0, r1); \
    if (hl && hr) { \
        bool left_first = l0 <= r0; \
        stack[sp] = left_first ? rref : lref; \
        sp += 1u; \
        cur = left_first ? lref : rref; \
    } else if (hl) { \
        cur = lref; \
    } else if (hr) { \
        cur = rref; \
    } else { \
        if (sp == 0u) return found; \
        sp -= 1u; \
        cur = stack[sp]; \
    }

// Resuming the BVH kernels' traversals (common/resume.glsl), on their locals cur, sp,
// found and stack: the words BVH_RS_* below, the stack from RESUME_LEVEL_WORDS.
// BVH_LEAF_CUT(tested): after testing leaf cur from step count `tested`, a leaf the
// step budget cut short leaves the loop with the rest of it in cur. BVH_LEAF_VISIT:
// the single-ray loops' (bvh.glsl, wide.glsl) leaf: test leaf cur (an any-hit trace
// returns at its first hit), cut it short where the budget ran out, then take the next
// node from the stack, or return when none is left.
#define BVH_RS_CUR 0u    // the next reference
#define BVH_RS_SP 1u
#define BVH_RS_FOUND 2u
#define BVH_RESUME_WORDS 3
#if BVH_RESUME_WORDS > RESUME_LEVEL_WORDS
#error "the BVH's resume words exceed RESUME_LEVEL_WORDS"
#endif
#define BVH_RESTORE \
    if (RESUME_PASS && g_resuming) { \
        g_resuming = false; \
        cur = rs_get(BVH_RS_CUR); \
        sp = rs_get(BVH_RS_SP); \
        found = rs_get(BVH_RS_FOUND) != 0u; \
        for (uint q = 0u; q < sp; q++) stack[q] = rs_get(RESUME_LEVEL_WORDS + q); \
    }
#define BVH_LEAF_CUT(tested) \
    tested = steps - tested; \
    if (tested <= (cur & BVH_LEAF_COUNT_MASK)) { \
        cur = bvh_leaf_rest(cur, tested); \
        break; \
    }
#define BVH_LEAF_VISIT \
    { \
        uint tested = steps; \
        if (bvh_leaf(cur, r, h, any_hit, true, steps)) { \
            found = true; \
            if (any_hit) return true; \
        } \
        BVH_LEAF_CUT(tested); \
        if (sp == 0u) return found; \
        sp -= 1u; \
        cur = stack[sp]; \
    }
#define BVH_SUSPEND \
    if (trace_suspend()) { \
        rs_put(BVH_RS_CUR, cur); \
        rs_put(BVH_RS_SP, sp); \
        rs_put(BVH_RS_FOUND, uint(found)); \
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

#endif
