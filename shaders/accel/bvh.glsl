// BVH traversal, for every builder (bvh-sah, lbvh, trbvh). Mirrors Bvh::traverse in
// src/accel/bvh/mod.rs, where the layout is documented: 64-byte inner nodes holding
// both children's boxes and references; a reference with bit 31 set is a leaf
// (first index << BVH_LEAF_COUNT_BITS | count - 1), 0xffffffff no child.
//
// Front to back: both child boxes are tested against [tmin, best t (1 + 1e-5)]; the
// nearer hit child is visited and the other pushed (BVH_NODE_STEP, the step the
// instances' top level takes too, common/bvh_leaf.glsl). Inner nodes are descended in an
// inner loop and leaves tested after it ("while-while"). The stack holds STACK_SIZE
// references (tree depth + 1, checked at build time); every trace takes at most
// TREE_STEPS steps (nodes + primitive tests), beyond which it stops and is resumed
// (common/resume.glsl). Its state: word 0 the next reference (a leaf cut short: the
// part of it left, bvh_leaf_rest), 1 sp, 2 found; the stack from RESUME_LEVEL_WORDS.

#define ACCEL_RESUMABLE 1
#include "common/bvh_leaf.glsl"

bool bvh_traverse(Ray r, inout Hit h, bool any_hit) {
    vec3 inv = safe_rcp3(r.dir);
    float e0, e1;
    if (!ray_box(ACCEL_BOX_MIN, ACCEL_BOX_MAX, r.origin, inv, r.tmin, r.tmax, e0, e1)) return false;
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
            BVH_NODE_STEP(node_texel, 4u * cur)
        }
        if ((cur & BVH_LEAF) == 0u) break;
        BVH_LEAF_VISIT
    }
    BVH_SUSPEND;
    return found;
}

// Packet traversal for coherent rays (camera rays, shadow rays toward point and
// directional lights): the subgroup walks one node sequence together. A child is
// entered when any active lane's ray enters it (subgroupAny), so every lane visits a
// superset of its own nodes and finds the same closest hit; the nearer child first by
// the lanes' majority. The node sequence, the stack and the step count are the same
// in every lane. A lane whose ray missed the scene box, or (any-hit) already found a
// hit, rides along without testing. Mirrors nothing on the CPU: it changes the work,
// not the result (tests/it/gpu_render.rs compares it with single-ray traversal).
bool bvh_traverse_packet(Ray r, inout Hit h, bool any_hit) {
    vec3 inv = safe_rcp3(r.dir);
    float e0, e1;
    bool live = ray_box(ACCEL_BOX_MIN, ACCEL_BOX_MAX, r.origin, inv, r.tmin, r.tmax, e0, e1);
    if (!subgroupAny(live)) return false;
    uint stack[STACK_SIZE];
    uint sp = 0u;
    uint cur = 0u;
    bool found = false;
    STEPS_START;
    while (steps < TREE_STEPS) {
        while ((cur & BVH_LEAF) == 0u && steps < TREE_STEPS) {
            steps += 1u;
            if (live) g_nodes += 1u;
            uvec4 a = node_texel(4u * cur);
            uvec4 b = node_texel(4u * cur + 1u);
            uvec4 c = node_texel(4u * cur + 2u);
            uvec4 d = node_texel(4u * cur + 3u);
            uint lref = a.w;
            uint rref = b.w;
            precise float limit = h.t * (1.0 + BVH_T_MARGIN);
            float l0, l1, r0, r1;
            bool hl = live && lref != BVH_EMPTY
                && ray_box(uintBitsToFloat(a.xyz), uintBitsToFloat(b.xyz), r.origin, inv, r.tmin, limit, l0, l1);
            bool hr = live && rref != BVH_EMPTY
                && ray_box(uintBitsToFloat(c.xyz), uintBitsToFloat(d.xyz), r.origin, inv, r.tmin, limit, r0, r1);
            bool any_l = subgroupAny(hl);
            bool any_r = subgroupAny(hr);
            // Votes for the left child first: lanes entering only it, or both with the
            // left nearer; against: the mirror cases.
            int vote = subgroupAdd(int(hl && (!hr || l0 <= r0)) - int(hr && (!hl || r0 < l0)));
            if (any_l && any_r) {
                bool left_first = vote >= 0;
                stack[sp] = left_first ? rref : lref;
                sp += 1u;
                cur = left_first ? lref : rref;
            } else if (any_l) {
                cur = lref;
            } else if (any_r) {
                cur = rref;
            } else {
                if (sp == 0u) return found;
                sp -= 1u;
                cur = stack[sp];
            }
        }
        if ((cur & BVH_LEAF) == 0u) break;
        uint tested = steps;
        if (bvh_leaf(cur, r, h, any_hit, live, steps)) {
            found = true;
            if (any_hit) live = false;
        }
        BVH_LEAF_CUT(tested);
        if (any_hit && !subgroupAny(live)) return found;
        if (sp == 0u) return found;
        sp -= 1u;
        cur = stack[sp];
    }
    // A lane whose trace is complete (it missed the scene box, or found its any hit)
    // ends here. Only the trace kernel has packets: it saves no state.
    if (live) trace_suspend();
    return found;
}

bool accel_closest(Ray r, inout Hit h) {
    return bvh_traverse(r, h, false);
}

// The resume kernel traces one ray per lane: a continued trace has its own stack, and
// packets change the work, not the result.
bool accel_closest_coherent(Ray r, inout Hit h) {
    return PACKET && !RESUME_PASS ? bvh_traverse_packet(r, h, false) : bvh_traverse(r, h, false);
}

bool accel_any_coherent(Ray r) {
    Hit h;
    h.t = r.tmax; h.prim = NO_PRIM; h.u = 0.0; h.v = 0.0;
    return PACKET && !RESUME_PASS ? bvh_traverse_packet(r, h, true) : bvh_traverse(r, h, true);
}

bool accel_any(Ray r) {
    Hit h;
    h.t = r.tmax; h.prim = NO_PRIM; h.u = 0.0; h.v = 0.0;
    return bvh_traverse(r, h, true);
}
