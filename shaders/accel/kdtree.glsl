// kd-tree traversal: front to back with a (node, tmax) stack, stopping as soon
// as every remaining cell starts after the best hit. Mirrors
// KdTree::traverse in src/accel/kdtree/mod.rs; node layout documented there:
//   uvec2 node: x = split bits (inner) or primitive count (leaf)
//               y = (above child or first index) << 2 | axis (3 = leaf)
// The stack holds SPEC_STACK_SIZE entries (tree depth + 1, checked at build time);
// every trace takes at most TREE_STEPS steps (nodes + primitive tests), beyond which
// it stops and is resumed (llvmpipe caps loop iterations; common/resume.glsl). Its
// state: the words KD_RS_* below; st_node from RESUME_LEVEL_WORDS, st_max STACK_SIZE
// words further.

#define ACCEL_RESUMABLE 1
#include "common/accel_texels.glsl"

#define KD_RS_NODE 0u
#define KD_RS_TMIN 1u
#define KD_RS_TMAX 2u
#define KD_RS_SP 3u
#define KD_RS_FOUND 4u
#define KD_RS_K_FIRST 5u  // the primitives of leaf `node` already tested
#define KD_RESUME_WORDS 6
#if KD_RESUME_WORDS > RESUME_LEVEL_WORDS
#error "the kd-tree's resume words exceed RESUME_LEVEL_WORDS"
#endif

// The stack holds (node, tmax) only: the cell popped next always starts where the
// last visited cell ended (its tmin is the current tmax, carried exactly), except
// for the sibling pushed by a ray lying inside a split plane, flagged IN_PLANE, which
// restarts at the ray's entry into the scene box (conservative: never skips a cell).
// Two arrays instead of three: on llvmpipe the stack lives in scratch memory and each
// array access is a per-lane gather or scatter, about 10% of the trace time.
const uint IN_PLANE = 0x80000000u;

bool kd_traverse(Ray r, inout Hit h, bool any_hit) {
    vec3 inv = safe_rcp3(r.dir);
    float tmin, tmax;
    if (!ray_box(ACCEL_BOX_MIN, ACCEL_BOX_MAX, r.origin, inv, r.tmin, r.tmax, tmin, tmax)) return false;
    float t_entry = tmin;
    uint st_node[STACK_SIZE];
    float st_max[STACK_SIZE];
    uint sp = 0u;
    uint node = 0u;
    bool found = false;
    STEPS_START;
    uint k_first = 0u;
    if (RESUME_PASS && g_resuming) {
        g_resuming = false;
        node = rs_get(KD_RS_NODE);
        tmin = rs_getf(KD_RS_TMIN);
        tmax = rs_getf(KD_RS_TMAX);
        sp = rs_get(KD_RS_SP);
        found = rs_get(KD_RS_FOUND) != 0u;
        k_first = rs_get(KD_RS_K_FIRST);
        for (uint q = 0u; q < sp; q++) {
            st_node[q] = rs_get(RESUME_LEVEL_WORDS + q);
            st_max[q] = rs_getf(RESUME_LEVEL_WORDS + STACK_SIZE + q);
        }
    }
    // Whether `node` was fetched and counted but not finished when the budget ran out.
    bool counted = false;
    while (steps < TREE_STEPS) {
        // Descend through inner nodes to a leaf ("while-while": on SIMD hardware the
        // lanes then test their leaves' primitives together).
        uvec2 nd = node_pair(node);
        steps += 1u;
        g_nodes += 1u;
        while ((nd.y & 3u) != 3u && steps < TREE_STEPS) {
            uint axis = nd.y & 3u;
            float split = uintBitsToFloat(nd.x);
            uint above = nd.y >> 2u;
            float o = r.origin[axis];
            float d = r.dir[axis];
            bool below_first = o < split || (o == split && d <= 0.0);
            uint first_child = below_first ? node + 1u : above;
            uint second_child = below_first ? above : node + 1u;
            if (o == split && d == 0.0) {
                st_node[sp] = second_child | IN_PLANE; st_max[sp] = tmax; sp += 1u;
                node = first_child;
            } else {
                precise float tplane = (split - o) * inv[axis];
                if (before(tmax, tplane) || tplane <= 0.0) {
                    node = first_child;
                } else if (before(tplane, tmin)) {
                    node = second_child;
                } else {
                    st_node[sp] = second_child; st_max[sp] = tmax; sp += 1u;
                    node = first_child;
                    tmax = tplane;
                }
            }
            nd = node_pair(node);
            steps += 1u;
            g_nodes += 1u;
        }
        counted = true;
        if ((nd.y & 3u) != 3u) break;
        uint first = nd.y >> 2u;
        uint count = nd.x;
        uint k = k_first;
        for (; k < count && steps < TREE_STEPS; k++) {
            steps += 1u;
            if (intersect_prim(accel_index(first + k), r, h)) {
                found = true;
                if (any_hit) return true;
            }
        }
        // A leaf cut short by the step budget resumes at its first untested primitive.
        if (k < count) {
            k_first = k;
            break;
        }
        k_first = 0u;
        counted = false;
        // Pop until a cell may still hold a hit before the best (no early return
        // on this cell's tmax: a ray inside a split plane pushes a sibling with
        // the same interval).
        bool resumed = false;
        while (sp > 0u) {
            sp -= 1u;
            uint entry = st_node[sp];
            float next_min = (entry & IN_PLANE) != 0u ? t_entry : tmax;
            tmax = st_max[sp];
            if (!(found && before(h.t, next_min))) {
                node = entry & ~IN_PLANE; tmin = next_min;
                resumed = true;
                break;
            }
        }
        if (!resumed) return found;
    }
    // The resumed trace fetches that node again and counts it then.
    if (counted) g_nodes -= 1u;
    if (trace_suspend()) {
        rs_put(KD_RS_NODE, node);
        rs_putf(KD_RS_TMIN, tmin);
        rs_putf(KD_RS_TMAX, tmax);
        rs_put(KD_RS_SP, sp);
        rs_put(KD_RS_FOUND, uint(found));
        rs_put(KD_RS_K_FIRST, k_first);
        for (uint q = 0u; q < sp; q++) {
            rs_put(RESUME_LEVEL_WORDS + q, st_node[q]);
            rs_putf(RESUME_LEVEL_WORDS + STACK_SIZE + q, st_max[q]);
        }
    }
    return found;
}

bool accel_closest(Ray r, inout Hit h) {
    return kd_traverse(r, h, false);
}

bool accel_any(Ray r) {
    Hit h;
    h.t = r.tmax; h.prim = NO_PRIM; h.u = 0.0; h.v = 0.0;
    return kd_traverse(r, h, true);
}
