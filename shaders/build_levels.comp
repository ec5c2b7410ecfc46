#version 460
// The schedule of one pass by height: the inner nodes with at least gamma primitives
// below them (a round's treelet roots; every inner node for gamma 0) listed by height,
// for one indirect dispatch per height (build_treelet, build_finalize, build_emit).
// A node's descendants all have lower heights, so going lowest first every node comes
// after its subtree, as in the CPU's bottom-up order. Push: n, a = mode, b = gamma.
//   COUNT (0):   listed nodes per height (threads over the n - 1 inner nodes).
//   SCAN (1):    one workgroup: offsets, dispatch arguments; counters zeroed.
//   SCATTER (2): the nodes into the list, grouped by height.
// A node BUILD_MAX_LEVELS or more high sets BUILD_ERR_LEVELS and is left out (the
// build then fails with that error). Every lane runs the atomics, idle lanes on the
// spare slot BUILD_MAX_LEVELS (see build_fit.comp for why).
#define USE_HEADER 1
#define USE_NODES 1
#define USE_LEVELS 1
#include "build/common.glsl"

layout(local_size_x = BUILD_GROUP) in;

const uint COUNT = BUILD_LEVELS_COUNT;
const uint SCAN = BUILD_LEVELS_SCAN;
const uint SCATTER = BUILD_LEVELS_SCATTER;

shared uint s_scan[BUILD_GROUP];
shared uint s_base[LV_SLOTS];

void main() {
    uint lid = gl_LocalInvocationID.x;
    if (pc.a == SCAN) {
        uint c = lid < BUILD_MAX_LEVELS ? levels[LV_COUNT + lid] : 0u;
        s_scan[lid] = c;
        barrier();
        // Inclusive scan (Hillis & Steele) over the BUILD_GROUP >= LV_SLOTS slots.
        for (uint d = 1u; d < BUILD_GROUP; d <<= 1u) {
            uint v = lid >= d ? s_scan[lid - d] : 0u;
            barrier();
            s_scan[lid] += v;
            barrier();
        }
        if (lid < BUILD_MAX_LEVELS) {
            uint groups = (c + BUILD_LEVEL_GROUP - 1u) / BUILD_LEVEL_GROUP;
            levels[LV_OFFSET + lid] = s_scan[lid] - c;
            levels[LV_ARGS + 3u * lid] = min(groups, 65535u);
            levels[LV_ARGS + 3u * lid + 1u] = (groups + 65534u) / 65535u;
            levels[LV_ARGS + 3u * lid + 2u] = 1u;
        }
        if (lid < LV_SLOTS) {
            levels[LV_COUNT + lid] = 0u;
            levels[LV_CURSOR + lid] = 0u;
        }
        return;
    }
    // Counted and placed per workgroup in shared memory first, then one global atomic
    // per height and workgroup: most nodes sit at the lowest heights, and one global
    // counter per height that every node hit would serialise a big GPU.
    if (lid < LV_SLOTS) s_scan[lid] = 0u;
    barrier();
    uint i = group_index() * BUILD_GROUP + lid;
    bool root = i + 1u < pc.n && aux[i].y >= pc.b;
    uint h = root ? levels[lv_height(i)] : BUILD_MAX_LEVELS;
    if (root && h >= BUILD_MAX_LEVELS) {
        atomicOr(hdr[BUILD_HDR_ERRORS], BUILD_ERR_LEVELS);
        root = false;
        h = BUILD_MAX_LEVELS;
    }
    uint k = atomicAdd(s_scan[h], 1u);
    barrier();
    // Lane s (< LV_SLOTS) adds the workgroup's count at height s; the other lanes add 0
    // to the spare slot.
    uint slot = min(lid, LV_SLOTS - 1u);
    uint here = lid < LV_SLOTS ? s_scan[slot] : 0u;
    barrier();
    if (pc.a == COUNT) {
        if (here > 0u) atomicAdd(levels[LV_COUNT + slot], here);
        return;
    }
    s_base[slot] = atomicAdd(levels[LV_CURSOR + slot], here);
    barrier();
    if (root) levels[LV_LIST + levels[LV_OFFSET + h] + s_base[h] + k] = i;
}
