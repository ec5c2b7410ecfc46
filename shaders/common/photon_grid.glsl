// SPPM's hash grid as its kernels read it (src/photon/hashgrid.rs, the layout): the
// header's box, cells and edge, a cell's bucket, and a photon's lookup. Needs the
// accessors PHOTON_HEADER(i), PHOTON_START(b), PHOTON_ENTRY(k) (uint words) and
// PHOTON_POINT(v) (vec4 position + radius) defined before it: storage buffers' elements
// in shaders/photon_grid.comp, texel fetches in the photon pass (common/sppm.glsl).
#ifndef ARBOR_PHOTON_GRID_GLSL
#define ARBOR_PHOTON_GRID_GLSL

#include "common/float_order.glsl"
#include "common/photon_holds.glsl"

vec3 photon_grid_min() {
    return vec3(order_float(PHOTON_HEADER(PHOTON_HDR_MIN)), order_float(PHOTON_HEADER(PHOTON_HDR_MIN + 1u)),
                order_float(PHOTON_HEADER(PHOTON_HDR_MIN + 2u)));
}

// hashgrid::hash: Teschner et al. 2003, wrapping 32-bit.
uint photon_grid_hash(uvec3 c, uint buckets) {
    return ((c.x * 73856093u) ^ (c.y * 19349663u) ^ (c.z * 83492791u)) % buckets;
}

// HashGrid::cell_of: the cell holding p, clamped into the grid.
uvec3 photon_grid_cell(vec3 p, vec3 lo, float edge, uvec3 res) {
    uvec3 c;
    for (int a = 0; a < 3; a++) {
        precise float k = floor((p[a] - lo[a]) / edge);
        c[a] = k > 0.0 ? uint(min(k, float(res[a] - 1u))) : 0u;
    }
    return c;
}

// HashGrid::lookup: the range of entries a photon at p tests (empty outside the box
// or over no points); each entry is a visible point to test with photon_holds.
struct GridLookup {
    uint first;
    uint end;
};
GridLookup grid_lookup_begin(vec3 p, uint n, uint buckets) {
    GridLookup g;
    g.first = 0u;
    g.end = 0u;
    vec3 lo = photon_grid_min();
    vec3 hi = vec3(order_float(PHOTON_HEADER(PHOTON_HDR_MAX)), order_float(PHOTON_HEADER(PHOTON_HDR_MAX + 1u)),
                   order_float(PHOTON_HEADER(PHOTON_HDR_MAX + 2u)));
    if (n == 0u || any(lessThan(p, lo)) || any(greaterThan(p, hi))) return g;
    float edge = uintBitsToFloat(PHOTON_HEADER(PHOTON_HDR_EDGE));
    uvec3 res = uvec3(PHOTON_HEADER(PHOTON_HDR_RES), PHOTON_HEADER(PHOTON_HDR_RES + 1u), PHOTON_HEADER(PHOTON_HDR_RES + 2u));
    uint b = photon_grid_hash(photon_grid_cell(p, lo, edge, res), buckets);
    g.first = PHOTON_START(b);
    g.end = PHOTON_START(b + 1u);
    return g;
}

// What a lookup does with visible point v, which holds p (the includer defines it:
// photon_grid.comp's test pass counts, the photon pass deposits).
void photon_visit(uint v, vec3 p);

// HashGrid::lookup: photon_visit for each point of p's bucket that holds p, testing at
// most `most` of them (the loop's bound); false when the bucket held more.
bool grid_walk(vec3 p, uint n, uint buckets, uint most) {
    GridLookup g = grid_lookup_begin(p, n, buckets);
    uint end = g.first + min(g.end - g.first, most);
    for (uint k = g.first; k < end; k++) {
        uint v = PHOTON_ENTRY(k);
        if (photon_holds(v, p)) photon_visit(v, p);
    }
    return g.end - g.first <= most;
}

#endif
