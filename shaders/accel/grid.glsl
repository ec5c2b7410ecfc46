// Uniform grid traversal by 3D-DDA (Amanatides & Woo 1987) in ray parameter t only.
// Mirrors Grid::traverse in src/accel/grid.rs, where the layout is documented:
//   accel_nodes: uvec4(res, cells), vec4(cell size, 0), then ncells + 1 cell starts
//   accel_indices: the primitives of cell c are [start[c], start[c + 1])
// The first cell comes from a binary search over the boundaries' t values, each step
// crosses the boundary with the smallest t, and a hit ends traversal only when it lies
// before the current cell's exit. Every trace takes at most TREE_STEPS steps (search
// steps, cells and primitive tests), beyond which it stops and is resumed
// (common/resume.glsl). Its state: the words GRID_RS_* below; the t of the next
// boundaries follow from the cell's indices.

#define ACCEL_RESUMABLE 1
#define GRID_RS_SEARCHED 0u  // whether the first-cell search was done (else the trace starts over)
#define GRID_RS_CELL 1u      // the cell's indices, three words
#define GRID_RS_K_FIRST 4u   // the primitives of that cell already tested
#define GRID_RS_FOUND 5u
#define GRID_RESUME_WORDS 6
#if GRID_RESUME_WORDS > RESUME_LEVEL_WORDS
#error "the grid's resume words exceed RESUME_LEVEL_WORDS"
#endif

// The head of this block is GpuGridHeader in src/accel/gpu_layout.rs.
// Node buffer: grid_res (16 bytes), grid_cell (16 bytes), then the cell starts.
#include "common/accel_texels.glsl"
#define grid_res node_texel(0u)
#define grid_cell uintBitsToFloat(node_texel(1u))

// Coordinate of boundary k on axis a; Grid::boundary.
float grid_boundary(uint a, uint k) {
    precise float b = ACCEL_BOX_MIN[a] + float(k) * grid_cell[a];
    return b;
}

// Ray parameter at boundary k on axis a.
float grid_tb(uint a, uint k, Ray r, vec3 inv) {
    precise float t = (grid_boundary(a, k) - r.origin[a]) * inv[a];
    return t;
}

bool grid_traverse(Ray r, inout Hit h, bool any_hit) {
    vec3 inv = safe_rcp3(r.dir);
    float t_enter, t_far;
    if (grid_res.w == 0u) return false;
    if (!ray_box(ACCEL_BOX_MIN, ACCEL_BOX_MAX, r.origin, inv, r.tmin, r.tmax, t_enter, t_far)) return false;
    const float INF = uintBitsToFloat(0x7f800000u);
    uvec3 res = grid_res.xyz;
    uvec3 idx = uvec3(0u);
    vec3 t_next = vec3(INF);
    STEPS_START;
    bool found = false;
    uint k_first = 0u;
    // A resumed trace past the search enters the search with its answer.
    bool searched = false;
    if (RESUME_PASS && g_resuming) {
        g_resuming = false;
        searched = rs_get(GRID_RS_SEARCHED) != 0u;
        idx = uvec3(rs_get(GRID_RS_CELL), rs_get(GRID_RS_CELL + 1u), rs_get(GRID_RS_CELL + 2u));
        k_first = rs_get(GRID_RS_K_FIRST);
        found = rs_get(GRID_RS_FOUND) != 0u;
    }
    bool cut = false;
    for (uint a = 0u; a < 3u; a++) {
        bool flat_axis = abs(inv[a]) >= 1e30;
        // Largest k whose boundary the ray at t_enter lies at or above.
        uint lo = searched ? idx[a] : 0u;
        uint hi = searched ? idx[a] : res[a] - 1u;
        while (lo < hi && steps < TREE_STEPS) {
            steps += 1u;
            uint mid = (lo + hi + 1u) / 2u;
            bool above;
            if (flat_axis) {
                above = grid_boundary(a, mid) <= r.origin[a];
            } else if (inv[a] > 0.0) {
                above = grid_tb(a, mid, r, inv) <= t_enter;
            } else {
                above = grid_tb(a, mid, r, inv) > t_enter;
            }
            if (above) lo = mid; else hi = mid - 1u;
        }
        cut = cut || lo < hi;
        idx[a] = lo;
        if (!flat_axis) t_next[a] = inv[a] > 0.0 ? grid_tb(a, lo + 1u, r, inv) : grid_tb(a, lo, r, inv);
    }
    // Whether the cell was counted but not finished when the budget ran out.
    bool counted = false;
    while (steps < TREE_STEPS) {
        steps += 1u;
        g_nodes += 1u;
        uint c = idx.x + res.x * (idx.y + res.y * idx.z);
        uint first = node_word(8u + (c));
        uint last = node_word(8u + (c + 1u));
        uint k = first + k_first;
        for (; k < last && steps < TREE_STEPS; k++) {
            steps += 1u;
            if (intersect_prim(accel_index(k), r, h)) {
                found = true;
                if (any_hit) return true;
            }
        }
        // A cell cut short by the step budget resumes at its first untested primitive.
        if (k < last) {
            k_first = k - first;
            counted = true;
            break;
        }
        k_first = 0u;
        uint a = 0u;
        if (t_next.y < t_next[a]) a = 1u;
        if (t_next.z < t_next[a]) a = 2u;
        float t_exit = t_next[a];
        if (before(h.t, t_exit) || isinf(t_exit)) return found;
        if (inv[a] > 0.0) {
            idx[a] += 1u;
            if (idx[a] >= res[a]) return found;
            t_next[a] = grid_tb(a, idx[a] + 1u, r, inv);
        } else {
            if (idx[a] == 0u) return found;
            idx[a] -= 1u;
            t_next[a] = grid_tb(a, idx[a], r, inv);
        }
    }
    // The resumed trace counts that cell again.
    if (counted) g_nodes -= 1u;
    if (trace_suspend()) {
        rs_put(GRID_RS_SEARCHED, uint(!cut));
        rs_put(GRID_RS_CELL, idx.x);
        rs_put(GRID_RS_CELL + 1u, idx.y);
        rs_put(GRID_RS_CELL + 2u, idx.z);
        rs_put(GRID_RS_K_FIRST, k_first);
        rs_put(GRID_RS_FOUND, uint(found));
    }
    return found;
}

bool accel_closest(Ray r, inout Hit h) {
    return grid_traverse(r, h, false);
}

bool accel_any(Ray r) {
    Hit h;
    h.t = r.tmax; h.prim = NO_PRIM; h.u = 0.0; h.v = 0.0;
    return grid_traverse(r, h, true);
}
