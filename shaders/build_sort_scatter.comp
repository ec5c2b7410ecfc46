#version 460
// Radix sort, pass 3 of 3: stable scatter. A tile is processed in BUILD_SORT_ITEMS
// rounds of BUILD_GROUP pairs, in order; within a round a pair's rank among equal
// digits comes from bit masks in shared memory (one bit per thread and digit), so no
// subgroup size is assumed. Push: n, a = shift, b = blocks.
#define USE_PAIRS 1
#define USE_PAIRS_OUT 1
#define USE_HIST 1
#include "build/common.glsl"

layout(local_size_x = BUILD_GROUP) in;

const uint WORDS = BUILD_GROUP / 32u;
shared uint s_base[256];
shared uint s_mask[256 * WORDS];

void main() {
    uint lid = gl_LocalInvocationID.x;
    uint tile = group_index();
    if (tile >= pc.b) return;
    s_base[lid] = hist[lid * pc.b + tile];
    uint base = tile * BUILD_GROUP * BUILD_SORT_ITEMS;
    uint word = lid / 32u;
    uint bit = 1u << (lid % 32u);
    for (uint it = 0u; it < BUILD_SORT_ITEMS; ++it) {
        for (uint w = 0u; w < WORDS; ++w) s_mask[lid * WORDS + w] = 0u;
        barrier();
        uint idx = base + it * BUILD_GROUP + lid;
        bool valid = idx < pc.n;
        uvec2 p = valid ? pairs[idx] : uvec2(0u);
        uint digit = (p.x >> pc.a) & 255u;
        if (valid) atomicOr(s_mask[digit * WORDS + word], bit);
        barrier();
        if (valid) {
            uint rank = bitCount(s_mask[digit * WORDS + word] & (bit - 1u));
            for (uint w = 0u; w < word; ++w) rank += bitCount(s_mask[digit * WORDS + w]);
            pairs_out[s_base[digit] + rank] = p;
        }
        barrier();
        uint added = 0u;
        for (uint w = 0u; w < WORDS; ++w) added += bitCount(s_mask[lid * WORDS + w]);
        s_base[lid] += added;
        barrier();
    }
}
