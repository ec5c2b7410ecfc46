#version 460
// Bottom-up fit with atomic visit counters (Karras 2012, section 4): one thread per
// leaf climbs; at each parent the first thread to arrive stops and the second, which
// finds both children done, handles the parent and climbs on (resetting the counter).
// A parent gets the union of its children's boxes, its primitive count, its cost with
// collapse (treelet::Restructure::new) and its height (leaves 0) for the schedule of
// the passes by height (build_levels.comp), whose counters are zeroed here.
// Push: n, ct, ci. A climb longer than BUILD_MAX_WALK sets BUILD_ERR_WALK.
#define USE_HEADER 1
#define USE_NODES 1
#define USE_LEVELS 1
#include "build/common.glsl"

// One subgroup per workgroup (SPEC_FIT_GROUP, set from the device's subgroup size).
layout(local_size_x_id = SPEC_FIT_GROUP) in;

shared uint s_climbing;

void main() {
    uint j = group_index() * gl_WorkGroupSize.x + gl_LocalInvocationID.x;
    bool climbing = j < pc.n;
    uint cur = pc.n - 1u + j;
    if (climbing) levels[lv_height(cur)] = 0u;
    for (uint w = j; w < LV_ARGS; w += pc.n) levels[w] = 0u;
    // Every lane runs the atomic at every step, idle lanes on the spare entry 2n-1:
    // llvmpipe returned wrong old values from an atomic that only some lanes ran.
    uint spare = 2u * pc.n - 1u;
    bool done = false;
    for (uint g = 0u; g < BUILD_MAX_WALK; ++g) {
        uint p = climbing ? aux[cur].x : NONE;
        climbing = p != NONE;
        memoryBarrierBuffer();
        uint seen = atomicAdd(aux[climbing ? p : spare].w, 1u);
        climbing = climbing && seen != 0u;
        if (climbing) {
            memoryBarrierBuffer();
            aux[p].w = 0u;
            uint l = node_left(p);
            uint r = node_right(p);
            vec3 lo = min(node_min(l), node_min(r));
            vec3 hi = max(node_max(l), node_max(r));
            uint count = aux[l].y + aux[r].y;
            precise float children = uintBitsToFloat(aux[l].z) + uintBitsToFloat(aux[r].z);
            nodes[2u * p].xyz = floatBitsToUint(lo);
            nodes[2u * p + 1u].xyz = floatBitsToUint(hi);
            aux[p].y = count;
            aux[p].z = floatBitsToUint(node_cost(lo, hi, count, children));
            levels[lv_height(p)] = 1u + max(levels[lv_height(l)], levels[lv_height(r)]);
            memoryBarrierBuffer();
            cur = p;
        }
        if (gl_LocalInvocationID.x == 0u) s_climbing = 0u;
        barrier();
        if (climbing) atomicAdd(s_climbing, 1u);
        barrier();
        done = s_climbing == 0u;
        barrier();
        if (done) break;
    }
    if (!done && gl_LocalInvocationID.x == 0u) atomicOr(hdr[BUILD_HDR_ERRORS], BUILD_ERR_WALK);
}
