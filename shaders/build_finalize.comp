#version 460
// Output-node counts and collapse decisions, by height: dispatched once per height,
// lowest first, over build_levels.comp's list of every inner node, so both children
// are final (treelet::Restructure::collapse_flags and the flattener's counts).
// With COLLAPSE, a node whose subtree is cheaper as one leaf (at most MAX_LEAF
// primitives) gets aux.z = COLLAPSED; any other node the number of output inner nodes
// in its subtree. Push: n, a = COLLAPSE (trbvh; the LBVH has no finalize pass, see
// build_emit.comp) or 0 (counts only), c = height, ci.
#define USE_HEADER 1
#define USE_NODES 1
#define USE_LEVELS 1
#include "build/common.glsl"

layout(local_size_x = BUILD_LEVEL_GROUP) in;

const uint COLLAPSE = BUILD_FINALIZE_COLLAPSE;

uint inner_nodes(uint i) {
    return (is_leaf(i) || aux[i].z == COLLAPSED) ? 0u : aux[i].z;
}

void main() {
    uint t = group_index() * BUILD_LEVEL_GROUP + gl_LocalInvocationID.x;
    uint h = pc.c;
    if (t >= levels[LV_CURSOR + h]) return;
    uint p = levels[LV_LIST + levels[LV_OFFSET + h] + t];
    uint count = aux[p].y;
    bool collapse = false;
    if (pc.a == COLLAPSE && count <= MAX_LEAF) {
        precise float leaf = (pc.ci * box_area(node_min(p), node_max(p))) * float(count);
        collapse = leaf <= uintBitsToFloat(aux[p].z);
    }
    aux[p].z = collapse ? COLLAPSED : 1u + inner_nodes(node_left(p)) + inner_nodes(node_right(p));
}
