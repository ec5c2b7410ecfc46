#version 460
// Output in the traversal layout (src/accel/bvh/mod.rs, shaders/accel/bvh.glsl), equal
// word for word to Bvh::flatten of the same canonical tree: inner nodes in preorder,
// leaf primitives in depth-first order. A node's preorder index and the depth-first
// position of its first primitive come from one walk to the root: every ancestor
// reached from its right child adds its left child's output-node and primitive counts.
// Thread t handles canonical node t: an output inner node (not collapsed, no collapsed
// ancestor) writes itself; a canonical leaf writes its primitive's index entry.
// A root that is a leaf or collapsed becomes one node with an empty right child.
// Push: n.
#define USE_HEADER 1
#define USE_NODES 1
#include "build/common.glsl"

layout(local_size_x = BUILD_GROUP) in;

layout(std430, set = 0, binding = BINDING_BUILD_OUT_NODES) writeonly buffer OutNodes { uvec4 out_nodes[]; };
layout(std430, set = 0, binding = BINDING_BUILD_OUT_INDICES) writeonly buffer OutIndices { uint out_indices[]; };

const uint LEAF_REF = 0x80000000u;
const uint EMPTY_REF = 0xffffffffu;

bool collapsed(uint i) { return !is_leaf(i) && aux[i].z == COLLAPSED; }
uint inner_nodes(uint i) { return (is_leaf(i) || collapsed(i)) ? 0u : aux[i].z; }

uint child_ref(uint c, uint pre, uint first) {
    if (is_leaf(c) || collapsed(c)) return LEAF_REF | (first << 3u) | (aux[c].y - 1u);
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

void main() {
    uint t = group_index() * BUILD_GROUP + gl_LocalInvocationID.x;
    uint n = pc.n;
    if (t >= 2u * n - 1u) return;
    bool leaf = is_leaf(t);
    if (!leaf && collapsed(t) && aux[t].x != NONE) return;
    // Walk to the root.
    uint pre = 0u;
    uint first = 0u;
    uint depth = 1u;
    bool hidden = false;
    uint c = t;
    uint g = 0u;
    for (; g < BUILD_MAX_WALK; ++g) {
        uint p = aux[c].x;
        if (p == NONE) break;
        if (collapsed(p)) hidden = true;
        uint l = node_left(p);
        pre += 1u;
        depth += 1u;
        if (node_right(p) == c) {
            pre += inner_nodes(l);
            first += aux[l].y;
        }
        c = p;
    }
    if (g == BUILD_MAX_WALK) {
        atomicOr(hdr[BUILD_HDR_ERRORS], BUILD_ERR_WALK);
        return;
    }
    if (leaf) out_indices[first] = node_left(t) & ~LEAF_FLAG;
    if (aux[t].x == NONE && (leaf || collapsed(t))) {
        // The whole tree is one leaf.
        write_node(0u, LEAF_REF | ((aux[t].y - 1u) & 7u), t, EMPTY_REF, t);
        hdr[BUILD_HDR_DEPTH] = 1u;
        hdr[BUILD_HDR_NODES] = 1u;
        return;
    }
    if (leaf || hidden) return;
    uint l = node_left(t);
    uint r = node_right(t);
    uint lref = child_ref(l, pre + 1u, first);
    uint rref = child_ref(r, pre + 1u + inner_nodes(l), first + aux[l].y);
    write_node(pre, lref, l, rref, r);
    atomicMax(hdr[BUILD_HDR_DEPTH], depth);
    if (pre == 0u) hdr[BUILD_HDR_NODES] = aux[t].z;
}
