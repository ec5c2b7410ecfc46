#version 460
// Output in the traversal layout (src/accel/bvh/mod.rs, shaders/accel/bvh.glsl), equal
// word for word to Bvh::flatten of the same canonical tree: inner nodes in preorder,
// leaf primitives in depth-first order. Top-down by height: ROOT (one thread) seeds
// the root, then TOP runs once per height, highest first, over build_levels.comp's
// list of every inner node (a parent is higher than its children, so its values are
// final). Each inner node p holds its preorder index (aux.w), the depth-first position
// of its first primitive (its height slot in the schedule, no longer needed) and its
// depth with a hidden bit (aux.x, the parent link, no longer needed); it hands them to
// its children: the left child follows p, the right child follows the left child's
// output nodes and primitives. An output inner node (not collapsed, no collapsed
// ancestor) writes itself; a canonical leaf child gets its primitive's index entry.
// A root that is a leaf or collapsed becomes one node with an empty right child.
// With b = UNFINALIZED (the LBVH, which collapses nothing and so needs no finalize
// pass) no node is collapsed and a subtree of k primitives has k - 1 inner nodes; aux.z
// still holds the fit's cost. The deepest output node has no inner output child, so
// only such a node bids for the depth (one word every node would hit; reading it first
// to skip the bid made llvmpipe slower). Push: n, a = mode, b, c = height.
#define USE_HEADER 1
#define USE_NODES 1
#define USE_LEVELS 1
#include "build/common.glsl"

layout(local_size_x = BUILD_LEVEL_GROUP) in;

layout(std430, set = 0, binding = BINDING_BUILD_OUT_NODES) writeonly buffer OutNodes { uvec4 out_nodes[]; };
layout(std430, set = 0, binding = BINDING_BUILD_OUT_INDICES) writeonly buffer OutIndices { uint out_indices[]; };

const uint ROOT = BUILD_EMIT_ROOT;
const uint TOP = BUILD_EMIT_TOP;
const uint LEAF_REF = BVH_LEAF_REF;
const uint EMPTY_REF = BVH_EMPTY_REF;
const uint HIDDEN = 0x80000000u;

const uint UNFINALIZED = BUILD_EMIT_UNFINALIZED;

bool collapsed(uint i) { return pc.b != UNFINALIZED && !is_leaf(i) && aux[i].z == COLLAPSED; }
uint inner_nodes(uint i) {
    if (is_leaf(i) || collapsed(i)) return 0u;
    return pc.b == UNFINALIZED ? aux[i].y - 1u : aux[i].z;
}

uint child_ref(uint c, uint pre, uint first) {
    if (is_leaf(c) || collapsed(c)) return LEAF_REF | (first << BVH_LEAF_COUNT_BITS) | (aux[c].y - 1u);
    return pre;
}

void write_node(uint at, uint lref, uint l, uint rref, uint r) {
    out_nodes[4u * at] = uvec4(nodes[2u * l].xyz, lref);
    out_nodes[4u * at + 1u] = uvec4(nodes[2u * l + 1u].xyz, rref);
    if (rref == EMPTY_REF) {
        out_nodes[4u * at + 2u] = uvec4(0u);
        out_nodes[4u * at + 3u] = uvec4(0u);
    } else {
        out_nodes[4u * at + 2u] = uvec4(nodes[2u * r].xyz, 0u);
        out_nodes[4u * at + 3u] = uvec4(nodes[2u * r + 1u].xyz, 0u);
    }
}

// Hands (preorder index, first primitive, depth | hidden) to child c.
void seed(uint c, uint pre, uint first, uint depth) {
    if (is_leaf(c)) {
        out_indices[first] = node_left(c) & ~LEAF_FLAG;
        return;
    }
    aux[c].w = pre;
    levels[lv_height(c)] = first;
    aux[c].x = depth;
}

void main() {
    if (pc.a == ROOT) {
        if (gl_GlobalInvocationID.x != 0u) return;
        // The root is node 0 (a leaf only when n = 1).
        if (is_leaf(0u) || collapsed(0u)) {
            write_node(0u, LEAF_REF | ((aux[0].y - 1u) & BVH_LEAF_COUNT_MASK), 0u, EMPTY_REF, 0u);
            hdr[BUILD_HDR_DEPTH] = 1u;
            hdr[BUILD_HDR_NODES] = 1u;
        } else {
            hdr[BUILD_HDR_NODES] = inner_nodes(0u);
        }
        seed(0u, 0u, 0u, 1u);
        return;
    }
    uint t = group_index() * BUILD_LEVEL_GROUP + gl_LocalInvocationID.x;
    uint h = pc.c;
    if (t >= levels[LV_CURSOR + h]) return;
    uint p = levels[LV_LIST + levels[LV_OFFSET + h] + t];
    uint pre = aux[p].w;
    uint first = levels[lv_height(p)];
    uint depth = aux[p].x & ~HIDDEN;
    bool hidden = (aux[p].x & HIDDEN) != 0u;
    uint l = node_left(p);
    uint r = node_right(p);
    uint pre_r = pre + 1u + inner_nodes(l);
    uint first_r = first + aux[l].y;
    uint below = (depth + 1u) | ((hidden || collapsed(p)) ? HIDDEN : 0u);
    seed(l, pre + 1u, first, below);
    seed(r, pre_r, first_r, below);
    if (hidden || collapsed(p)) return;
    write_node(pre, child_ref(l, pre + 1u, first), l, child_ref(r, pre_r, first_r), r);
    if (pre_r == pre + 1u && inner_nodes(r) == 0u) atomicMax(hdr[BUILD_HDR_DEPTH], depth);
}
