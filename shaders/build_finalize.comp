#version 460
// Collapse decisions top-down-ready, by height (the trbvh path; build_fit.comp's
// FINALIZE | COLLAPSE does the same by climbing): dispatched once per height, lowest
// first, over build_levels.comp's list of every inner node, so both children are final.
// A node whose subtree is one leaf or cheaper as one (at most MAX_LEAF primitives)
// gets aux.z = COLLAPSED, any other the number of output inner nodes in its subtree.
// Push: n, c = height, ci.
#define USE_HEADER 1
#define USE_NODES 1
#define USE_LEVELS 1
#include "build/common.glsl"

layout(local_size_x = BUILD_TREELET_GROUP) in;

uint inner_nodes(uint i) {
    return (is_leaf(i) || aux[i].z == COLLAPSED) ? 0u : aux[i].z;
}

void main() {
    uint t = group_index() * BUILD_TREELET_GROUP + gl_LocalInvocationID.x;
    uint h = pc.c;
    if (t >= levels[LV_CURSOR + h]) return;
    uint p = levels[LV_LIST + levels[LV_OFFSET + h] + t];
    uint count = aux[p].y;
    bool collapse = false;
    if (count <= MAX_LEAF) {
        precise float leaf = (pc.ci * box_area(node_min(p), node_max(p))) * float(count);
        collapse = leaf <= uintBitsToFloat(aux[p].z);
    }
    aux[p].z = collapse ? COLLAPSED : 1u + inner_nodes(node_left(p)) + inner_nodes(node_right(p));
}
