#version 460
// Radix sort, pass 3 of 3: stable scatter. One workgroup of one subgroup
// (SPEC_SCATTER_GROUP threads, 8..BUILD_SCATTER_MAX_GROUP) walks a tile of BUILD_GROUP x BUILD_SORT_ITEMS
// pairs in order, a workgroup's width at a time; within a step a pair's rank among
// equal digits comes from bit masks in shared memory (one bit per thread and digit),
// so no subgroup operation is needed. The lowest thread of each digit then advances
// that digit's base and clears its mask. A one-subgroup workgroup keeps the barriers
// cheap (llvmpipe runs them as coroutine switches). Push: n, a = shift, b = blocks.
#define USE_PAIRS 1
#define USE_PAIRS_OUT 1
#define USE_HIST 1
#include "build/common.glsl"

layout(local_size_x_id = SPEC_SCATTER_GROUP) in;

const uint TILE = BUILD_GROUP * BUILD_SORT_ITEMS;
// Mask words per digit: two, so at most 64 threads (the code below reads both words).
#if BUILD_SCATTER_MAX_GROUP > 64
#error "build_sort_scatter.comp keeps two mask words per digit: at most 64 threads"
#endif
const uint MAXW = 2u;
shared uint s_base[256];
shared uint s_mask[256 * MAXW];

void main() {
    uint lid = gl_LocalInvocationID.x;
    uint g = gl_WorkGroupSize.x;
    uint words = (g + 31u) / 32u;
    uint tile = group_index();
    if (tile >= pc.b) return;
    for (uint d = lid; d < 256u; d += g) {
        s_base[d] = hist[d * pc.b + tile];
        s_mask[d * MAXW] = 0u;
        s_mask[d * MAXW + 1u] = 0u;
    }
    barrier();
    uint base = tile * TILE;
    uint word = lid / 32u;
    uint bit = 1u << (lid % 32u);
    for (uint it = 0u; it < TILE / g; ++it) {
        uint idx = base + it * g + lid;
        bool valid = idx < pc.n;
        uvec2 p = valid ? pairs[idx] : uvec2(0u);
        uint digit = (p.x >> pc.a) & 255u;
        if (valid) atomicOr(s_mask[digit * MAXW + word], bit);
        barrier();
        uint total = 0u;
        uint lowest = 0u;
        if (valid) {
            uint m0 = s_mask[digit * MAXW];
            uint m1 = words > 1u ? s_mask[digit * MAXW + 1u] : 0u;
            uint mine = word == 0u ? m0 : m1;
            uint rank = bitCount(mine & (bit - 1u)) + (word == 1u ? bitCount(m0) : 0u);
            pairs_out[s_base[digit] + rank] = p;
            total = bitCount(m0) + bitCount(m1);
            lowest = m0 != 0u ? uint(findLSB(m0)) : 32u + uint(findLSB(m1));
        }
        barrier();
        if (valid && lowest == lid) {
            s_base[digit] += total;
            s_mask[digit * MAXW] = 0u;
            s_mask[digit * MAXW + 1u] = 0u;
        }
        barrier();
    }
}
