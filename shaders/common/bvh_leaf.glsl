// What both BVH kernels (bvh.glsl, bvh4.glsl; the binary kernel's single-ray and
// packet traversals) share: the child-reference encoding of src/accel/bvh/mod.rs and
// the test of one leaf.
#ifndef ARBOR_BVH_LEAF_GLSL
#define ARBOR_BVH_LEAF_GLSL

#include "common/accel_texels.glsl"

const uint BVH_LEAF = 0x80000000u;
const uint BVH_EMPTY = 0xffffffffu;
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

#endif
