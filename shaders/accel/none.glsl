// Brute force with a scene-box early-out: every primitive against every ray.
// Interface shared by every shaders/accel/*.glsl:
//   bool accel_closest(Ray r, inout Hit h);   // nearest hit in (tmin, tmax)
//   bool accel_any(Ray r);                    // any hit in (tmin, tmax)
// Both count into g_nodes / g_tests. (bvh.glsl adds accel_closest_coherent and
// accel_any_coherent, its packet traversals; trace.comp gives the others these.)
//
// llvmpipe (lavapipe) allows each shader invocation 65535 loop iterations in total,
// over all loops, and silently breaks the invocation beyond that. For scenes whose
// plain loops would cross that, the host picks the kernel compiled with BRUTE_UNROLL
// 8 or 32 (build.rs: trace_none_tris_x8, ...), whose primitive loops run unrolled by
// hand that many times (no loop in the IR for the inner step); plain loops
// (BRUTE_UNROLL = 1) are the fastest, unrolled code is several times slower on
// llvmpipe, so the host picks the smallest factor that fits
// (src/render/dispatch/kernel.rs, `LoopBounds`).

#define TEST_TRI(k) if (b + k < n) { if (intersect_triangle(b + k, r, h)) { found = true; ANY_EXIT } }
#define TEST_SPH(k) if (b + k < n) { if (intersect_sphere(b + k, r, h)) { found = true; ANY_EXIT } }
#define UNROLLED_8(T) T(0u) T(1u) T(2u) T(3u) T(4u) T(5u) T(6u) T(7u)
#define UNROLLED(T) UNROLLED_8(T) \
    T(8u) T(9u) T(10u) T(11u) T(12u) T(13u) T(14u) T(15u) \
    T(16u) T(17u) T(18u) T(19u) T(20u) T(21u) T(22u) T(23u) \
    T(24u) T(25u) T(26u) T(27u) T(28u) T(29u) T(30u) T(31u)

bool scene_box(Ray r) {
    float enter, exit_t;
    g_nodes += 1u;
    return ray_box(params.scene_min, params.scene_max, r.origin, safe_rcp3(r.dir), r.tmin, r.tmax, enter, exit_t);
}

// Tests primitives [0, n) with TEST (TEST_TRI or TEST_SPH), unrolled BRUTE_UNROLL times.
// Only the chosen loop is compiled: the module carries no code the kernel cannot run.
#if BRUTE_UNROLL == 32
#define BRUTE_LOOP(n_expr, TEST) \
    { \
        uint n = n_expr; \
        for (uint b = 0u; b < n; b += 32u) { UNROLLED(TEST) } \
    }
#elif BRUTE_UNROLL == 8
#define BRUTE_LOOP(n_expr, TEST) \
    { \
        uint n = n_expr; \
        for (uint b = 0u; b < n; b += 8u) { UNROLLED_8(TEST) } \
    }
#else
#define BRUTE_LOOP(n_expr, TEST) \
    { \
        uint n = n_expr; \
        uint b = 0u; \
        for (uint k = 0u; k < n; k++) { TEST(k) } \
    }
#endif

// Every primitive of the scene; ANY_EXIT decides what a hit does besides recording it.
// The counts are specialization constants, not `params.triangle_count`: lavapipe compiles a
// shader again at every dispatch for a uniform that bounds a loop.
layout(constant_id = SPEC_TRIANGLE_COUNT) const uint TRIANGLE_COUNT = 0u;
layout(constant_id = SPEC_SPHERE_COUNT) const uint SPHERE_COUNT = 0u;
#if HAS_TRIANGLES && HAS_SPHERES
#define BRUTE_ALL BRUTE_LOOP(TRIANGLE_COUNT, TEST_TRI) BRUTE_LOOP(SPHERE_COUNT, TEST_SPH)
#elif HAS_TRIANGLES
#define BRUTE_ALL BRUTE_LOOP(TRIANGLE_COUNT, TEST_TRI)
#else
#define BRUTE_ALL BRUTE_LOOP(SPHERE_COUNT, TEST_SPH)
#endif

bool accel_closest(Ray r, inout Hit h) {
    if (!scene_box(r)) return false;
    bool found = false;
#define ANY_EXIT
    BRUTE_ALL
#undef ANY_EXIT
    return found;
}

bool accel_any(Ray r) {
    if (!scene_box(r)) return false;
    Hit h;
    h.t = r.tmax;
    h.prim = NO_PRIM;
    bool found = false;
#define ANY_EXIT return true;
    BRUTE_ALL
#undef ANY_EXIT
    return found;
}
