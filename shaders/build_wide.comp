#version 460
#extension GL_EXT_control_flow_attributes : require
// The binary tree the emit pass wrote (out_nodes, the flattener's preorder) collapsed
// into W-wide nodes (W = 4 or 8) in the bvh4 / bvh8 layout, equal word for
// word to WideBvh::collapse of the same tree (src/accel/bvh/wide.rs). A wide node's
// children are open_wide's: its two children, then the inner child of largest area
// (the first of equal ones) opened in place while fewer than W; the inner ones among
// them are wide nodes one level down.
//   SEED    flags cleared, the root flagged and alone on level 0's list.
//   MARK    once per wide level L from the top (indirect, over level L's list): flags
//           each wide node's inner children and appends them to level L + 1's list,
//           counting its workgroups into level L + 1's dispatch arguments.
//   COUNT   flagged nodes per block of BUILD_GROUP x BUILD_WIDE_ITEMS output nodes.
//   SCAN    one workgroup: exclusive prefix sums of the block counts; the total.
//   NUMBER  wide[i] = the wide node of output node i (NONE if it was opened), and the
//           inverse map: wide nodes are numbered in the binary preorder, which is the
//           wide tree's preorder (a wide node's children cover its binary subtree left
//           to right); the order of the lists does not matter.
//   WRITE   one thread per wide node (the host knows the count): its W children,
//           inner ones referenced through wide[].
// The `wide` buffer, in words (src/accel/bvh/gpu_build.rs sizes it):
//   [0, n)             per output node: flag, then its wide node or NONE
//   [n, n + b)         per-block counts, then their prefix sums (b = pc.b blocks)
//   LISTS, 2 x HALF    the two levels' lists (level L in list L % 2), then the
//                      inverse map (wide node -> output node) over both
//   LEVELS             per level: listed nodes (BUILD_LV_SLOTS), dispatch arguments
//                      (3 words each)
// Push: n, a = mode, b = blocks, c = level (MARK). W is a specialization constant
// (SPEC_WIDE_WIDTH), so every loop over a node's children unrolls to W steps.
#define USE_HEADER 1
#include "build/common.glsl"

layout(local_size_x = BUILD_GROUP) in;

layout(std430, set = 0, binding = BINDING_BUILD_OUT_NODES) readonly buffer OutNodes { uvec4 out_nodes[]; };
layout(std430, set = 0, binding = BINDING_BUILD_WIDE) coherent buffer Wide { uint wide[]; };
layout(std430, set = 0, binding = BINDING_BUILD_WIDE_NODES) writeonly buffer WideNodes { uint wide_nodes[]; };

const uint SEED = BUILD_WIDE_SEED;
const uint MARK = BUILD_WIDE_MARK;
const uint COUNT = BUILD_WIDE_COUNT;
const uint SCAN = BUILD_WIDE_SCAN;
const uint NUMBER = BUILD_WIDE_NUMBER;
const uint WRITE = BUILD_WIDE_WRITE;
const uint LEAF_REF = BVH_LEAF_REF;
const uint EMPTY_REF = BVH_EMPTY_REF;
layout(constant_id = SPEC_WIDE_WIDTH) const uint W = 4u;

uint half_list() { return pc.n / 2u + 1u; }
uint lists() { return pc.n + pc.b; }
uint level_count(uint l) { return lists() + 2u * half_list() + l; }
uint level_args(uint l) { return lists() + 2u * half_list() + BUILD_LV_SLOTS + 3u * l; }

shared uint s_scan[BUILD_GROUP];

// The children of a wide node: references (binary preorder index or leaf reference)
// and boxes.
uint kref[W];
vec3 klo[W];
vec3 khi[W];
uint nk;

// open_wide of output node b (src/accel/bvh/wide.rs), with the same area and the same
// choice among equal areas (the first). Every loop is unrolled so that the arrays are
// indexed by constants only (registers, not memory, on llvmpipe too); slots from nk on
// hold EMPTY_REF.
void open_kids(uint b) {
    uvec4 l0 = out_nodes[4u * b], l1 = out_nodes[4u * b + 1u];
    uvec4 l2 = out_nodes[4u * b + 2u], l3 = out_nodes[4u * b + 3u];
    [[unroll]] for (uint k = 0u; k < W; k++) {
        kref[k] = EMPTY_REF;
        klo[k] = vec3(0.0);
        khi[k] = vec3(0.0);
    }
    // The left child always exists (a lone root's is its leaf).
    kref[0] = l0.w; klo[0] = uintBitsToFloat(l0.xyz); khi[0] = uintBitsToFloat(l1.xyz);
    kref[1] = l1.w;
    if (l1.w != EMPTY_REF) { klo[1] = uintBitsToFloat(l2.xyz); khi[1] = uintBitsToFloat(l3.xyz); }
    nk = l1.w == EMPTY_REF ? 1u : 2u;
    [[unroll]] for (uint round = 0u; round < W - 2u; round++) {
        uint best = W;
        uint r = 0u;
        float best_area = 0.0;
        [[unroll]] for (uint k = 0u; k < W; k++) {
            float a = box_area(klo[k], khi[k]);
            if ((kref[k] & LEAF_REF) == 0u && (best == W || a > best_area)) {
                best = k;
                best_area = a;
                r = kref[k];
            }
        }
        if (nk < W && best != W) {
            // An inner node other than a lone root has two children: those after
            // `best` move up by one, and both children take its place.
            uvec4 a0 = out_nodes[4u * r], a1 = out_nodes[4u * r + 1u];
            uvec4 a2 = out_nodes[4u * r + 2u], a3 = out_nodes[4u * r + 3u];
            [[unroll]] for (int k = int(W) - 1; k >= 1; k--) {
                if (uint(k) > best + 1u) {
                    kref[k] = kref[k - 1]; klo[k] = klo[k - 1]; khi[k] = khi[k - 1];
                } else if (uint(k) == best + 1u) {
                    kref[k] = a1.w; klo[k] = uintBitsToFloat(a2.xyz); khi[k] = uintBitsToFloat(a3.xyz);
                }
            }
            [[unroll]] for (uint k = 0u; k < W; k++) {
                if (k == best) { kref[k] = a0.w; klo[k] = uintBitsToFloat(a0.xyz); khi[k] = uintBitsToFloat(a1.xyz); }
            }
            nk++;
        }
    }
}

uint thread_index() {
    return group_index() * BUILD_GROUP + gl_LocalInvocationID.x;
}

// Whether output node i is a wide node (before NUMBER).
uint marked(uint i) {
    return (i < hdr[BUILD_HDR_NODES] && wide[i] != 0u) ? 1u : 0u;
}

void main() {
    uint lid = gl_LocalInvocationID.x;
    if (pc.a == SEED) {
        uint i = thread_index();
        if (i < pc.n) wide[i] = i == 0u ? 1u : 0u;
        if (i < BUILD_LV_SLOTS) {
            wide[level_count(i)] = i == 0u ? 1u : 0u;
            wide[level_args(i)] = i == 0u ? 1u : 0u;
            wide[level_args(i) + 1u] = 1u;
            wide[level_args(i) + 2u] = 1u;
        }
        if (i == 0u) {
            wide[lists()] = 0u;
            hdr[BUILD_HDR_WIDE_DEPTH] = 1u;
        }
        return;
    }
    if (pc.a == MARK) {
        uint t = thread_index();
        uint l = pc.c;
        bool live = t < wide[level_count(l)];
        if (t == 0u) atomicMax(hdr[BUILD_HDR_WIDE_DEPTH], l + 1u);
        uint m = 0u;
        if (live) {
            open_kids(wide[lists() + (l % 2u) * half_list() + t]);
            [[unroll]] for (uint k = 0u; k < W; k++) m += (kref[k] & LEAF_REF) == 0u ? 1u : 0u;
        }
        // The workgroup reserves its places on level l + 1's list with one global
        // atomic (one per wide node would serialise a big GPU on that counter), then
        // counts the next level's workgroups that its reservation begins.
        if (lid == 0u) s_scan[0] = 0u;
        barrier();
        uint local = atomicAdd(s_scan[0], m);
        barrier();
        if (lid == 0u) {
            uint total = s_scan[0];
            uint at = total > 0u ? atomicAdd(wide[level_count(l + 1u)], total) : 0u;
            uint groups = (at + total + BUILD_GROUP - 1u) / BUILD_GROUP - (at + BUILD_GROUP - 1u) / BUILD_GROUP;
            if (groups > 0u) atomicAdd(wide[level_args(l + 1u)], groups);
            s_scan[1] = at;
        }
        barrier();
        uint at = s_scan[1] + local;
        uint next = lists() + ((l + 1u) % 2u) * half_list();
        if (live) {
            [[unroll]] for (uint k = 0u; k < W; k++) {
                if ((kref[k] & LEAF_REF) == 0u) {
                    wide[kref[k]] = 1u;
                    wide[next + at] = kref[k];
                    at++;
                }
            }
        }
        return;
    }
    // A 2D grid may have more workgroups than blocks (Context::grid_for).
    if ((pc.a == COUNT || pc.a == NUMBER) && group_index() >= pc.b) return;
    // Each thread counts, then numbers, BUILD_WIDE_ITEMS consecutive output nodes.
    uint first = thread_index() * BUILD_WIDE_ITEMS;
    if (pc.a == COUNT) {
        uint c = 0u;
        for (uint k = 0u; k < BUILD_WIDE_ITEMS; k++) c += marked(first + k);
        s_scan[lid] = c;
        barrier();
        for (uint s = BUILD_GROUP / 2u; s > 0u; s >>= 1u) {
            if (lid < s) s_scan[lid] += s_scan[lid + s];
            barrier();
        }
        if (lid == 0u) wide[pc.n + group_index()] = s_scan[0];
        return;
    }
    if (pc.a == SCAN) {
        // Exclusive scan of pc.b block counts in place, BUILD_GROUP at a time.
        uint carry = 0u;
        for (uint base = 0u; base < pc.b; base += BUILD_GROUP) {
            uint i = base + lid;
            uint c = i < pc.b ? wide[pc.n + i] : 0u;
            s_scan[lid] = c;
            barrier();
            for (uint d = 1u; d < BUILD_GROUP; d <<= 1u) {
                uint v = lid >= d ? s_scan[lid - d] : 0u;
                barrier();
                s_scan[lid] += v;
                barrier();
            }
            if (i < pc.b) wide[pc.n + i] = carry + s_scan[lid] - c;
            carry += s_scan[BUILD_GROUP - 1u];
            barrier();
        }
        if (lid == 0u) hdr[BUILD_HDR_WIDE_NODES] = carry;
        return;
    }
    if (pc.a == NUMBER) {
        uint c = 0u;
        for (uint k = 0u; k < BUILD_WIDE_ITEMS; k++) c += marked(first + k);
        s_scan[lid] = c;
        barrier();
        for (uint d = 1u; d < BUILD_GROUP; d <<= 1u) {
            uint v = lid >= d ? s_scan[lid - d] : 0u;
            barrier();
            s_scan[lid] += v;
            barrier();
        }
        uint at = wide[pc.n + group_index()] + s_scan[lid] - c;
        for (uint k = 0u; k < BUILD_WIDE_ITEMS; k++) {
            uint i = first + k;
            if (i >= pc.n) break;
            uint f = marked(i);
            wide[i] = f != 0u ? at : NONE;
            if (f != 0u) wide[lists() + at] = i;
            at += f;
        }
        return;
    }
    // WRITE
    uint j = thread_index();
    if (j >= hdr[BUILD_HDR_WIDE_NODES]) return;
    open_kids(wide[lists() + j]);
    uint row = W / 4u;
    uint base = j * WIDE_NODE_PLANES * row;
    [[unroll]] for (uint k = 0u; k < W; k++) {
        uint r = kref[k];
        if ((r & LEAF_REF) == 0u) r = wide[r];
        // Empty slots: EMPTY_REF with an all-zero box (open_kids cleared them).
        uint planes[WIDE_NODE_PLANES] = uint[WIDE_NODE_PLANES](floatBitsToUint(klo[k].x), floatBitsToUint(klo[k].y), floatBitsToUint(klo[k].z),
            floatBitsToUint(khi[k].x), floatBitsToUint(khi[k].y), floatBitsToUint(khi[k].z), r);
        [[unroll]] for (uint p = 0u; p < WIDE_NODE_PLANES; p++) {
            wide_nodes[4u * (base + p * row + k / 4u) + k % 4u] = planes[p];
        }
    }
}
