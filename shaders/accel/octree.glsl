// Octree traversal, stackless and parametric. Mirrors Octree::traverse in
// src/accel/octree.rs, where the layout is documented:
//   accel_nodes: vec4 root min, vec4 root max, then 8-byte nodes
//     x: bit 31 leaf (bits 0..31 count) or inner (bits 0..8 child mask)
//     y: first index (leaf) or first existing child (inner); octant k is at
//        y + bitCount(mask & ((1 << k) - 1)); bit 0/1/2 of k = upper half in x/y/z
// From t (the ray's entry), descend from the root (or from the last cell's parent
// when the ray leaves that cell strictly before the parent) to the cell the ray is in just
// after t, comparing t with the mid-planes' t (zero direction components decide by
// the origin); test the leaf; move t to the cell's exit, a face that is bit for bit
// an ancestor's centre, so the next descent crosses it. Stops when the best hit lies
// before the cell's exit or the exit is the root's. At most TREE_STEPS steps (nodes
// and primitive tests) per trace, beyond which the pixel is flagged.

// The head of this block is GpuOctreeHeader in src/accel/gpu_layout.rs.
// Node buffer: oct_min (16 bytes), oct_max (16 bytes), then 8-byte nodes.
#include "common/accel_texels.glsl"
#define oct_min uintBitsToFloat(node_texel(0u))
#define oct_max uintBitsToFloat(node_texel(1u))

const uint OCT_LEAF = 0x80000000u;

// The ray's exit from the box [mn, mx]: the nearest far face over moving axes.
float oct_exit(vec3 mn, vec3 mx, vec3 o, vec3 inv, bvec3 flat_axis, bvec3 up) {
    vec3 face = mix(mn, mx, up);
    precise vec3 tf = (face - o) * inv;
    tf = mix(tf, vec3(uintBitsToFloat(0x7f800000u)), flat_axis);
    return min(min(tf.x, tf.y), tf.z);
}

bool oct_traverse(Ray r, inout Hit h, bool any_hit) {
    vec3 inv = safe_rcp3(r.dir);
    vec3 rmin = oct_min.xyz;
    vec3 rmax = oct_max.xyz;
    float t_enter, t_far;
    if (!ray_box(rmin, rmax, r.origin, inv, r.tmin, r.tmax, t_enter, t_far)) return false;
    bvec3 flat_axis = greaterThanEqual(abs(inv), vec3(1e30));
    bvec3 up = greaterThan(inv, vec3(0.0));
    float root_exit = oct_exit(rmin, rmax, r.origin, inv, flat_axis, up);
    float t = t_enter;
    bool found = false;
    STEPS_START;
    // Where each descent starts: the root, or the last cell's parent (Octree::traverse).
    uint start = 0u;
    vec3 start_mn = rmin;
    vec3 start_mx = rmax;
    while (steps < TREE_STEPS) {
        vec3 mn = start_mn;
        vec3 mx = start_mx;
        uint node = start;
        uvec2 nd = node_pair(4u + (node));
        uint parent = node;
        vec3 parent_mn = mn;
        vec3 parent_mx = mx;
        steps += 1u;
        g_nodes += 1u;
        while ((nd.x & OCT_LEAF) == 0u && steps < TREE_STEPS) {
            parent = node; parent_mn = mn; parent_mx = mx;
            precise vec3 c = mn * 0.5 + mx * 0.5;
            precise vec3 tm = (c - r.origin) * inv;
            bvec3 crossed = lessThanEqual(tm, vec3(t));
            bvec3 moving_upper = equal(up, crossed);
            bvec3 origin_upper = greaterThanEqual(r.origin, c);
            bvec3 upper = bvec3(flat_axis.x ? origin_upper.x : moving_upper.x,
                                flat_axis.y ? origin_upper.y : moving_upper.y,
                                flat_axis.z ? origin_upper.z : moving_upper.z);
            uint k = (upper.x ? 1u : 0u) | (upper.y ? 2u : 0u) | (upper.z ? 4u : 0u);
            mn = mix(mn, c, upper);
            mx = mix(c, mx, upper);
            uint mask = nd.x & 0xffu;
            if ((mask & (1u << k)) == 0u) break; // absent octant: empty space
            node = nd.y + uint(bitCount(mask & ((1u << k) - 1u)));
            nd = node_pair(4u + (node));
            steps += 1u;
            g_nodes += 1u;
        }
        if ((nd.x & OCT_LEAF) != 0u) {
            uint first = nd.y;
            uint count = nd.x & ~OCT_LEAF;
            for (uint k = 0u; k < count && steps < TREE_STEPS; k++) {
                steps += 1u;
                if (intersect_prim(accel_index(first + k), r, h)) {
                    found = true;
                    if (any_hit) return true;
                }
            }
        }
        if (steps >= TREE_STEPS) break;
        float t_exit = oct_exit(mn, mx, r.origin, inv, flat_axis, up);
        if (before(h.t, t_exit) || t_exit >= root_exit) return found;
        if (t_exit < oct_exit(parent_mn, parent_mx, r.origin, inv, flat_axis, up)) {
            start = parent; start_mn = parent_mn; start_mx = parent_mx;
        } else {
            start = 0u; start_mn = rmin; start_mx = rmax;
        }
        t = t_exit;
    }
    g_overflow = true;
    return found;
}

bool trace_closest(Ray r, inout Hit h) {
    return oct_traverse(r, h, false);
}

bool trace_any(Ray r) {
    Hit h;
    h.t = r.tmax; h.prim = NO_PRIM; h.u = 0.0; h.v = 0.0;
    return oct_traverse(r, h, true);
}
