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
// and primitive tests) per trace, beyond which it stops and is resumed
// (common/resume.glsl). Its state: words 0 t, 1 start, 2..5 start_mn, 5..8 start_mx,
// 8 found, 9 where (0 the next descent, 1 within a descent at `node`, 2 in leaf
// `node`), 10 node, 11..14 its box min, 14..17 max, 17 parent, 18..21 its box min,
// 21..24 max, 24 the primitives of the leaf already tested.

#define ACCEL_RESUMABLE 1

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
    // Where a resumed trace continues, and the primitives of its leaf already tested.
    uint where = 0u;
    uint r_node = 0u, r_parent = 0u, k_first = 0u;
    vec3 r_mn = vec3(0.0), r_mx = vec3(0.0), r_pmn = vec3(0.0), r_pmx = vec3(0.0);
    if (RESUME_PASS && g_resuming) {
        g_resuming = false;
        t = rs_getf(0u);
        start = rs_get(1u);
        start_mn = vec3(rs_getf(2u), rs_getf(3u), rs_getf(4u));
        start_mx = vec3(rs_getf(5u), rs_getf(6u), rs_getf(7u));
        found = rs_get(8u) != 0u;
        where = rs_get(9u);
        r_node = rs_get(10u);
        r_mn = vec3(rs_getf(11u), rs_getf(12u), rs_getf(13u));
        r_mx = vec3(rs_getf(14u), rs_getf(15u), rs_getf(16u));
        r_parent = rs_get(17u);
        r_pmn = vec3(rs_getf(18u), rs_getf(19u), rs_getf(20u));
        r_pmx = vec3(rs_getf(21u), rs_getf(22u), rs_getf(23u));
        k_first = rs_get(24u);
    }
    while (steps < TREE_STEPS) {
        bool within = RESUME_PASS && where != 0u;
        bool in_leaf = RESUME_PASS && where == 2u;
        vec3 mn = within ? r_mn : start_mn;
        vec3 mx = within ? r_mx : start_mx;
        uint node = within ? r_node : start;
        uvec2 nd = node_pair(4u + (node));
        uint parent = in_leaf ? r_parent : node;
        vec3 parent_mn = in_leaf ? r_pmn : mn;
        vec3 parent_mx = in_leaf ? r_pmx : mx;
        where = 0u;
        steps += 1u;
        g_nodes += 1u;
        bool empty = false;
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
            if ((mask & (1u << k)) == 0u) { // absent octant: empty space
                empty = true;
                break;
            }
            node = nd.y + uint(bitCount(mask & ((1u << k) - 1u)));
            nd = node_pair(4u + (node));
            steps += 1u;
            g_nodes += 1u;
        }
        if ((nd.x & OCT_LEAF) != 0u) {
            uint first = nd.y;
            uint count = nd.x & ~OCT_LEAF;
            uint k = k_first;
            for (; k < count && steps < TREE_STEPS; k++) {
                steps += 1u;
                if (intersect_prim(accel_index(first + k), r, h)) {
                    found = true;
                    if (any_hit) return true;
                }
            }
            // A leaf cut short by the step budget resumes at its first untested primitive.
            if (k < count) where = 2u;
            k_first = k < count ? k : 0u;
        } else if (!empty) {
            where = 1u; // the budget ran out within the descent
        }
        if (where != 0u) {
            if (RESUME_PASS) {
                r_node = node; r_mn = mn; r_mx = mx;
                r_parent = parent; r_pmn = parent_mn; r_pmx = parent_mx;
            }
            // The resumed trace fetches that node again and counts it then.
            g_nodes -= 1u;
            break;
        }
        float t_exit = oct_exit(mn, mx, r.origin, inv, flat_axis, up);
        if (before(h.t, t_exit) || t_exit >= root_exit) return found;
        if (t_exit < oct_exit(parent_mn, parent_mx, r.origin, inv, flat_axis, up)) {
            start = parent; start_mn = parent_mn; start_mx = parent_mx;
        } else {
            start = 0u; start_mn = rmin; start_mx = rmax;
        }
        t = t_exit;
    }
    if (trace_suspend()) {
        rs_putf(0u, t);
        rs_put(1u, start);
        rs_putf(2u, start_mn.x); rs_putf(3u, start_mn.y); rs_putf(4u, start_mn.z);
        rs_putf(5u, start_mx.x); rs_putf(6u, start_mx.y); rs_putf(7u, start_mx.z);
        rs_put(8u, uint(found));
        rs_put(9u, where);
        rs_put(10u, r_node);
        rs_putf(11u, r_mn.x); rs_putf(12u, r_mn.y); rs_putf(13u, r_mn.z);
        rs_putf(14u, r_mx.x); rs_putf(15u, r_mx.y); rs_putf(16u, r_mx.z);
        rs_put(17u, r_parent);
        rs_putf(18u, r_pmn.x); rs_putf(19u, r_pmn.y); rs_putf(20u, r_pmn.z);
        rs_putf(21u, r_pmx.x); rs_putf(22u, r_pmx.y); rs_putf(23u, r_pmx.z);
        rs_put(24u, k_first);
    }
    return found;
}

bool accel_closest(Ray r, inout Hit h) {
    return oct_traverse(r, h, false);
}

bool accel_any(Ray r) {
    Hit h;
    h.t = r.tmax; h.prim = NO_PRIM; h.u = 0.0; h.v = 0.0;
    return oct_traverse(r, h, true);
}
