// The lecture's kd-tree over visible points as the photon pass reads it
// (src/photon/kdtree.rs, the layout: 32-byte nodes in preorder, each bounding its
// subtree's spheres). Needs the accessors PHOTON_TREE_NODE(i) (two vec4 a node: min +
// point bits, max + end bits) and PHOTON_POINT(v) (vec4 position + radius) before it,
// and PHOTON_TREE_STACK, the deepest tree it searches (floor(log2 n) + 1).
#ifndef ARBOR_PHOTON_TREE_GLSL
#define ARBOR_PHOTON_TREE_GLSL

#include "common/photon_holds.glsl"

// What a lookup does with visible point v, which holds p (the includer defines it:
// photon_tree.comp counts, the photon pass deposits).
void photon_visit(uint v, vec3 p);

// PointTree::lookup: photon_visit for each point of the tree's n nodes that holds p.
void tree_walk(vec3 p, uint n) {
    if (n == 0u) return;
    uint stack[PHOTON_TREE_STACK + 1];
    uint sp = 0u;
    stack[sp++] = 0u;
    // Every node is visited at most once.
    for (uint step = 0u; step < n && sp > 0u; step++) {
        uint k = stack[--sp];
        vec4 lo = PHOTON_TREE_NODE(2u * k);
        vec4 hi = PHOTON_TREE_NODE(2u * k + 1u);
        if (any(lessThan(p, lo.xyz)) || any(greaterThan(p, hi.xyz))) continue;
        uint v = floatBitsToUint(lo.w);
        if (photon_holds(v, p)) photon_visit(v, p);
        uint m = floatBitsToUint(hi.w) - k;
        if (m / 2u + 1u < m) stack[sp++] = k + 1u + m / 2u;
        if (m > 1u) stack[sp++] = k + 1u;
    }
}

#endif
