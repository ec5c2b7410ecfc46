// Shared by the GPU BVH build kernels (shaders/build_*.comp); the driver is
// src/accel/bvh/gpu_build.rs, which documents the pipeline and the buffers.
//
// Canonical tree (what the CPU builders call `Binary`): inner nodes 0 .. n-2, leaf j
// (the j-th sorted primitive) is node n-1+j. Per node:
//   nodes[2i]     = uvec4(min xyz as float bits, left)
//   nodes[2i + 1] = uvec4(max xyz as float bits, right)
//     inner: left, right = child node indices
//     leaf:  left = LEAF_FLAG | primitive, right = 1
//   aux[i] = uvec4(parent (NONE at the root), primitive count, cost bits, visit counter)
//     after the finalize pass aux[i].z = COLLAPSED if the subtree becomes one leaf,
//     else the number of output inner nodes in the subtree.
// Every `precise` keeps the compiler from fusing multiply-adds: costs must round as
// the CPU's do, so both builders make the same tree.
#ifndef ARBOR_BUILD_GLSL
#define ARBOR_BUILD_GLSL

layout(push_constant) uniform BuildPush {
    uint n;      // primitives
    uint a;      // kernel-specific (see each kernel)
    uint b;
    uint c;
    float ct;    // SAH traversal cost (src/accel/sah.rs)
    float ci;    // SAH intersection cost
    float keep;  // restructure only below cost * keep
    uint d;
} pc;

const uint NONE = 0xffffffffu;
const uint LEAF_FLAG = BUILD_LEAF_FLAG;
const uint COLLAPSED = 0x80000000u;
const uint MAX_LEAF = BVH_MAX_LEAF;

// Linear workgroup index of a 2D dispatch (Context::grid_for).
uint group_index() {
    return gl_WorkGroupID.y * gl_NumWorkGroups.x + gl_WorkGroupID.x;
}

#include "common/float_order.glsl"

// sah::area: 2 (ex ey + ey ez + ez ex), same operation order.
float box_area(vec3 lo, vec3 hi) {
    precise vec3 e = hi - lo;
    precise float s = e.x * e.y + e.y * e.z;
    precise float s2 = s + e.z * e.x;
    precise float a = 2.0 * s2;
    return a;
}

// treelet::Restructure::node_cost: the cheaper of splitting (C_T A + children) and,
// for at most MAX_LEAF primitives, one leaf (C_I A N).
float node_cost(vec3 lo, vec3 hi, uint count, float children) {
    float a = box_area(lo, hi);
    precise float split = pc.ct * a + children;
    if (count <= MAX_LEAF) {
        precise float leaf = (pc.ci * a) * float(count);
        return min(split, leaf);
    }
    return split;
}

#ifdef USE_HEADER
layout(std430, set = 0, binding = BINDING_BUILD_HEADER) coherent buffer BuildHeader { uint hdr[]; };
#endif
#ifdef USE_PRIM_BOUNDS
layout(std430, set = 0, binding = BINDING_BUILD_PRIM_BOUNDS) buffer PrimBounds { vec4 prim_bounds[]; };
#endif
#ifdef USE_PAIRS
layout(std430, set = 0, binding = BINDING_BUILD_PAIRS) buffer Pairs { uvec2 pairs[]; };
#endif
#ifdef USE_PAIRS_OUT
layout(std430, set = 0, binding = BINDING_BUILD_PAIRS_OUT) writeonly buffer PairsOut { uvec2 pairs_out[]; };
#endif
#ifdef USE_HIST
layout(std430, set = 0, binding = BINDING_BUILD_HIST) buffer Hist { uint hist[]; };
#endif
#if defined(USE_NODES) || defined(USE_AUX)
layout(std430, set = 0, binding = BINDING_BUILD_AUX) coherent buffer Aux { uvec4 aux[]; };
#endif
#ifdef USE_NODES
layout(std430, set = 0, binding = BINDING_BUILD_NODES) coherent buffer Nodes { uvec4 nodes[]; };

vec3 node_min(uint i) { return uintBitsToFloat(nodes[2u * i].xyz); }
vec3 node_max(uint i) { return uintBitsToFloat(nodes[2u * i + 1u].xyz); }
uint node_left(uint i) { return nodes[2u * i].w; }
uint node_right(uint i) { return nodes[2u * i + 1u].w; }
bool is_leaf(uint i) { return (nodes[2u * i].w & LEAF_FLAG) != 0u; }
#endif

#ifdef USE_LEVELS
// The schedule of the passes by height (build_levels.comp), in words:
//   LV_COUNT + h   listed nodes of height h, counted (zeroed again by the scan)
//   LV_OFFSET + h  first slot of height h in the list
//   LV_CURSOR + h  nodes of height h placed; after the scatter, how many there are
//   LV_ARGS + 3h   indirect dispatch arguments of height h (2D grid, 1)
//   LV_LIST + i    the listed nodes (treelet roots, or every inner node), by height
//   lv_height(i)   height of node i (a leaf 0, an inner node 1 + its higher child's),
//                  for the 2n - 1 nodes and the spare entry 2n - 1
// Index BUILD_MAX_LEVELS of each per-height array is a spare for idle lanes' atomics.
layout(std430, set = 0, binding = BINDING_BUILD_LEVELS) coherent buffer Levels { uint levels[]; };
// The offsets come from src/gpu/bindings.rs (BUILD_LV_*).
const uint LV_SLOTS = BUILD_LV_SLOTS;
const uint LV_COUNT = BUILD_LV_COUNT;
const uint LV_OFFSET = BUILD_LV_OFFSET;
const uint LV_CURSOR = BUILD_LV_CURSOR;
const uint LV_ARGS = BUILD_LV_ARGS;
const uint LV_LIST = BUILD_LV_LIST;
uint lv_height(uint i) { return LV_LIST + pc.n + i; }
#endif

#endif
