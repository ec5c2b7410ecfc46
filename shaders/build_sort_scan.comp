#version 460
// Radix sort, pass 2 of 3: exclusive prefix sum over all hist entries, in place, by
// one workgroup (each thread sums a contiguous chunk, the chunk totals are scanned in
// shared memory, then each chunk is rewritten). Push: n = entries.
#define USE_HIST 1
#include "build/common.glsl"

layout(local_size_x = BUILD_GROUP) in;

shared uint s_sum[BUILD_GROUP];

void main() {
    uint lid = gl_LocalInvocationID.x;
    uint chunk = (pc.n + BUILD_GROUP - 1u) / BUILD_GROUP;
    uint begin = min(lid * chunk, pc.n);
    uint end = min(begin + chunk, pc.n);
    uint total = 0u;
    for (uint i = begin; i < end; ++i) total += hist[i];
    s_sum[lid] = total;
    barrier();
    // Hillis-Steele inclusive scan of the chunk totals.
    for (uint off = 1u; off < BUILD_GROUP; off <<= 1u) {
        uint v = lid >= off ? s_sum[lid - off] : 0u;
        barrier();
        s_sum[lid] += v;
        barrier();
    }
    uint run = s_sum[lid] - total;
    for (uint i = begin; i < end; ++i) {
        uint v = hist[i];
        hist[i] = run;
        run += v;
    }
}
