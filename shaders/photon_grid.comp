#version 460
// SPPM's hash grid over visible points, built on the device by a counting sort: the
// layout and arithmetic of src/photon/hashgrid.rs, its oracle, word for word. Passes
// (specialization constant SPEC_GRID_MODE; src/photon/device.rs runs them in order):
//   PHOTON_GRID_CLEAR    the header to an empty box, the buckets' counts to zero
//   PHOTON_GRID_BOUNDS   the spheres' box and the largest radius, by atomics on
//                        order-preserving uints (the header starts at min = ~0, max 0)
//   PHOTON_GRID_FRAME    one thread: cells per axis and the cell edge
//   PHOTON_GRID_COUNT    each point's distinct buckets (at most 27), counted into starts
//   PHOTON_GRID_SCAN     one workgroup: the counts into exclusive starts (and cursors),
//                        starts[buckets] and the header's total
//   PHOTON_GRID_SCATTER  each point into its buckets' entries (order within a bucket
//                        is the atomics'; a lookup does not depend on it), those past
//                        the entries' capacity left out (the header's total says how
//                        many there are: the host grows the entries and builds again)
//   PHOTON_GRID_PROBE    for tests: each query photon's lookup (`grid_lookup`, as the
//                        photon pass will make it): the points found and the sum of
//                        their indices + 1
#extension GL_GOOGLE_include_directive : require
#extension GL_KHR_shader_subgroup_arithmetic : require
#extension GL_KHR_shader_subgroup_vote : require
#extension GL_KHR_shader_subgroup_basic : require

layout(local_size_x = PHOTON_GROUP) in;

// The pass this pipeline runs: one pipeline a pass, each with only its own code.
layout(constant_id = SPEC_GRID_MODE) const uint MODE = PHOTON_GRID_CLEAR;

layout(push_constant) uniform GridPush {
    uint unused;
    uint n;        // visible points
    uint buckets;  // the number of points, at least 1
    uint extra;    // PHOTON_GRID_SCATTER: the entries' capacity; PHOTON_GRID_PROBE: the query photons
} pc;

layout(std430, set = 0, binding = BINDING_PHOTON_HEADER) buffer GridHeader { uint header[]; };
layout(std430, set = 0, binding = BINDING_PHOTON_POINTS) readonly buffer GridPoints { vec4 points[]; }; // position, radius
layout(std430, set = 0, binding = BINDING_PHOTON_STARTS) buffer GridStarts { uint starts[]; };
layout(std430, set = 0, binding = BINDING_PHOTON_CURSOR) buffer GridCursor { uint cursor[]; };
layout(std430, set = 0, binding = BINDING_PHOTON_ENTRIES) buffer GridEntries { uint entries[]; };
layout(std430, set = 0, binding = BINDING_PHOTON_QUERIES) readonly buffer GridQueries { vec4 queries[]; };
layout(std430, set = 0, binding = BINDING_PHOTON_FOUND) writeonly buffer GridFound { uvec2 found[]; };

#define PHOTON_HEADER(i) header[i]
#define PHOTON_START(b) starts[b]
#define PHOTON_ENTRY(k) entries[k]
#define PHOTON_POINT(v) points[v]
#include "common/photon_grid.glsl"

// HashGrid::buckets_of: the distinct buckets of the cells that point i's sphere box
// overlaps, in the order first met (at most 27).
uint point_buckets(uint i, out uint seen[27]) {
    vec3 lo = photon_grid_min();
    float edge = uintBitsToFloat(header[PHOTON_HDR_EDGE]);
    uvec3 res = uvec3(header[PHOTON_HDR_RES], header[PHOTON_HDR_RES + 1u], header[PHOTON_HDR_RES + 2u]);
    vec4 pr = points[i];
    precise vec3 a = pr.xyz - vec3(pr.w);
    precise vec3 b = pr.xyz + vec3(pr.w);
    uvec3 c0 = photon_grid_cell(a, lo, edge, res);
    uvec3 c1 = photon_grid_cell(b, lo, edge, res);
    uint m = 0u;
    for (uint z = c0.z; z <= c1.z && z < c0.z + 3u; z++) {
        for (uint y = c0.y; y <= c1.y && y < c0.y + 3u; y++) {
            for (uint x = c0.x; x <= c1.x && x < c0.x + 3u; x++) {
                uint h = photon_grid_hash(uvec3(x, y, z), pc.buckets);
                bool fresh = true;
                for (uint k = 0u; k < m; k++) fresh = fresh && seen[k] != h;
                if (fresh) {
                    seen[m] = h;
                    m += 1u;
                }
            }
        }
    }
    return m;
}

shared uint s_sum[PHOTON_GROUP];

uvec2 g_found = uvec2(0u);
void photon_visit(uint v, vec3 p) { g_found += uvec2(1u, v + 1u); }

void main() {
    uint i = gl_GlobalInvocationID.x;
    if (MODE == PHOTON_GRID_CLEAR) {
        if (i < PHOTON_HDR_WORDS) header[i] = i >= PHOTON_HDR_MIN && i < PHOTON_HDR_MIN + 3u ? 0xffffffffu : 0u;
        if (i <= pc.buckets) starts[i] = 0u;
    } else if (MODE == PHOTON_GRID_BOUNDS) {
        // Each subgroup reduces its points first, so that one lane a subgroup (not
        // every point) takes the header's atomics. Radius 0: the pixel has no visible
        // point this iteration (SPPM's camera pass), and neither has a lane past n.
        vec4 pr = i < pc.n ? points[i] : vec4(0.0);
        bool valid = pr.w > 0.0;
        precise vec3 a = pr.xyz - vec3(pr.w);
        precise vec3 b = pr.xyz + vec3(pr.w);
        uint lo[3], hi[3];
        for (uint k = 0u; k < 3u; k++) {
            lo[k] = subgroupMin(valid ? float_order(a[k]) : 0xffffffffu);
            hi[k] = subgroupMax(valid ? float_order(b[k]) : 0u);
        }
        // A positive float's bits order as the float does.
        uint radius = subgroupMax(valid ? floatBitsToUint(pr.w) : 0u);
        bool any = subgroupAny(valid);
        if (subgroupElect() && any) {
            for (uint k = 0u; k < 3u; k++) {
                atomicMin(header[PHOTON_HDR_MIN + k], lo[k]);
                atomicMax(header[PHOTON_HDR_MAX + k], hi[k]);
            }
            atomicMax(header[PHOTON_HDR_RADIUS], radius);
        }
    } else if (MODE == PHOTON_GRID_FRAME) {
        if (i != 0u) return;
        vec3 lo = photon_grid_min();
        vec3 hi = vec3(order_float(header[PHOTON_HDR_MAX]), order_float(header[PHOTON_HDR_MAX + 1u]),
                       order_float(header[PHOTON_HDR_MAX + 2u]));
        float radius = uintBitsToFloat(header[PHOTON_HDR_RADIUS]);
        if (!(radius > 0.0)) {
            // No point has a radius: one cell, which no lookup reaches.
            for (uint a = 0u; a < 3u; a++) header[PHOTON_HDR_RES + a] = 1u;
            header[PHOTON_HDR_EDGE] = floatBitsToUint(1.0);
            return;
        }
        precise vec3 extent = hi - lo;
        float edge = radius;
        for (uint a = 0u; a < 3u; a++) {
            precise float cells = floor(extent[a] / radius);
            uint res = cells >= float(PHOTON_GRID_MAX_RES) ? PHOTON_GRID_MAX_RES : max(uint(cells), 1u);
            header[PHOTON_HDR_RES + a] = res;
            precise float e = extent[a] / float(res);
            edge = max(edge, e);
        }
        header[PHOTON_HDR_EDGE] = floatBitsToUint(edge);
    } else if (MODE == PHOTON_GRID_COUNT) {
        if (i >= pc.n || !(points[i].w > 0.0)) return;
        uint seen[27];
        uint m = point_buckets(i, seen);
        for (uint k = 0u; k < m; k++) atomicAdd(starts[seen[k]], 1u);
    } else if (MODE == PHOTON_GRID_SCAN) {
        // One workgroup: each thread sums a run of counts, thread 0 scans the sums,
        // each thread writes its run's starts.
        uint lid = gl_LocalInvocationID.x;
        uint per = (pc.buckets + PHOTON_GROUP - 1u) / PHOTON_GROUP;
        uint begin = min(lid * per, pc.buckets);
        uint end = min(begin + per, pc.buckets);
        uint sum = 0u;
        for (uint k = begin; k < end; k++) sum += starts[k];
        s_sum[lid] = sum;
        barrier();
        if (lid == 0u) {
            uint run = 0u;
            for (uint t = 0u; t < PHOTON_GROUP; t++) {
                uint v = s_sum[t];
                s_sum[t] = run;
                run += v;
            }
            starts[pc.buckets] = run;
            header[PHOTON_HDR_TOTAL] = run;
        }
        barrier();
        uint run = s_sum[lid];
        for (uint k = begin; k < end; k++) {
            uint c = starts[k];
            starts[k] = run;
            cursor[k] = run;
            run += c;
        }
    } else if (MODE == PHOTON_GRID_SCATTER) {
        if (i >= pc.n || !(points[i].w > 0.0)) return;
        uint seen[27];
        uint m = point_buckets(i, seen);
        for (uint k = 0u; k < m; k++) {
            uint at = atomicAdd(cursor[seen[k]], 1u);
            if (at < pc.extra) entries[at] = i;
        }
    } else if (MODE == PHOTON_GRID_PROBE) {
        if (i >= pc.extra) return;
        grid_walk(queries[i].xyz, pc.n, pc.buckets, 0xffffffffu);
        found[i] = g_found;
    }
}
