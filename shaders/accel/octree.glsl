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
// (common/resume.glsl), with the state of OCT_RS_* below.

#define ACCEL_RESUMABLE 1

// The traversal's resume state, words of its level (rs_get / rs_put): t, the
// descent's start node and box, found, where (0 the next descent, 1 within a descent
// at r_node, 2 in leaf r_node), r_node and its box, its parent and the parent's box,
// and the primitives of the leaf already tested. A box is six words, min xyz then
// max xyz. Plain integers, so that the preprocessor can check the bound.
#define OCT_RS_T 0
#define OCT_RS_START 1
#define OCT_RS_START_BOX 2
#define OCT_RS_FOUND 8
#define OCT_RS_WHERE 9
#define OCT_RS_NODE 10
#define OCT_RS_NODE_BOX 11
#define OCT_RS_PARENT 17
#define OCT_RS_PARENT_BOX 18
#define OCT_RS_K_FIRST 24
#define OCT_RESUME_WORDS (OCT_RS_K_FIRST + 1)
#if OCT_RESUME_WORDS > RESUME_LEVEL_WORDS
#error the octree's resume state does not fit in RESUME_LEVEL_WORDS
#endif

// Box [mn, mx] at words at..at + 6 of the resume state, and back.
void oct_box_put(uint at, vec3 mn, vec3 mx) {
    rs_putf(at, mn.x); rs_putf(at + 1u, mn.y); rs_putf(at + 2u, mn.z);
    rs_putf(at + 3u, mx.x); rs_putf(at + 4u, mx.y); rs_putf(at + 5u, mx.z);
}
void oct_box_get(uint at, out vec3 mn, out vec3 mx) {
    mn = vec3(rs_getf(at), rs_getf(at + 1u), rs_getf(at + 2u));
    mx = vec3(rs_getf(at + 3u), rs_getf(at + 4u), rs_getf(at + 5u));
}

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
        t = rs_getf(OCT_RS_T);
        start = rs_get(OCT_RS_START);
        oct_box_get(OCT_RS_START_BOX, start_mn, start_mx);
        found = rs_get(OCT_RS_FOUND) != 0u;
        where = rs_get(OCT_RS_WHERE);
        r_node = rs_get(OCT_RS_NODE);
        oct_box_get(OCT_RS_NODE_BOX, r_mn, r_mx);
        r_parent = rs_get(OCT_RS_PARENT);
        oct_box_get(OCT_RS_PARENT_BOX, r_pmn, r_pmx);
        k_first = rs_get(OCT_RS_K_FIRST);
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
        rs_putf(OCT_RS_T, t);
        rs_put(OCT_RS_START, start);
        oct_box_put(OCT_RS_START_BOX, start_mn, start_mx);
        rs_put(OCT_RS_FOUND, uint(found));
        rs_put(OCT_RS_WHERE, where);
        rs_put(OCT_RS_NODE, r_node);
        oct_box_put(OCT_RS_NODE_BOX, r_mn, r_mx);
        rs_put(OCT_RS_PARENT, r_parent);
        oct_box_put(OCT_RS_PARENT_BOX, r_pmn, r_pmx);
        rs_put(OCT_RS_K_FIRST, k_first);
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
