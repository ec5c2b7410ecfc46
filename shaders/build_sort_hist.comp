#version 460
// Radix sort, pass 1 of 3 per digit: how many keys of each 8-bit digit every tile of
// BUILD_GROUP x BUILD_SORT_ITEMS pairs holds. hist[digit * blocks + tile] (digit-major,
// so one exclusive scan gives every tile's output offset per digit).
// Push: n, a = shift of the digit, b = blocks (tiles).
#define USE_PAIRS 1
#define USE_HIST 1
#include "build/common.glsl"

layout(local_size_x = BUILD_GROUP) in;

shared uint s_count[256];

void main() {
    uint lid = gl_LocalInvocationID.x;
    uint tile = group_index();
    if (tile >= pc.b) return;
    s_count[lid] = 0u;
    barrier();
    uint base = tile * BUILD_GROUP * BUILD_SORT_ITEMS;
    for (uint it = 0u; it < BUILD_SORT_ITEMS; ++it) {
        uint idx = base + it * BUILD_GROUP + lid;
        if (idx < pc.n) atomicAdd(s_count[(pairs[idx].x >> pc.a) & 255u], 1u);
    }
    barrier();
    hist[lid * pc.b + tile] = s_count[lid];
}
