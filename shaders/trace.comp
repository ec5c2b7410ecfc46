#version 460
// The trace kernel, one thread per pixel, for each integrator (SPEC_INTEGRATOR):
// Whitted (the preview: direct light, mirrors, glass split; common/whitted.glsl), path
// tracing (common/path.glsl), or SPPM's passes (common/sppm.glsl: one thread a pixel or
// a photon). Each thread runs samples [z, w) of pixels
// [x, x + y) of `dispatch_range` (the pixel buffer's header).
// Compiled once per (structure, geometry, integrator) variant by build.rs: exactly one
// ACCEL_* macro is set, HAS_TRIANGLES / HAS_SPHERES decide which buffers exist,
// TRACE_ENTRY which integrator main() runs (SPEC_INTEGRATOR must agree: the host picks
// the module by it); with RAY_BATCH (the rays_* kernels) it traces rays from a buffer
// instead (batch_main).
#extension GL_GOOGLE_include_directive : require
#extension GL_KHR_shader_subgroup_vote : require
#extension GL_KHR_shader_subgroup_arithmetic : require

layout(local_size_x = WORKGROUP_SIZE) in;

layout(constant_id = SPEC_LIGHTS) const uint LIGHT_COUNT = 0u;
layout(constant_id = SPEC_MAX_DEPTH) const uint MAX_DEPTH = 8u;
layout(constant_id = SPEC_STACK_SIZE) const uint STACK_SIZE = 1u;
// The steps one trace may take: the dispatch header's (DISPATCH_TRACE_STEPS), read once
// by main(). A specialization constant would make each budget a pipeline of its own.
uint TREE_STEPS = 0u;
#ifndef BRUTE_UNROLL
#define BRUTE_UNROLL 1 // build.rs compiles brute force at each of BRUTE_UNROLL_FACTORS
#endif
layout(constant_id = SPEC_INTERSECT) const uint INTERSECT_MODE = 0u;
layout(constant_id = SPEC_DIFFUSE_PROBE) const bool DIFFUSE_PROBE = false;
layout(constant_id = SPEC_INTEGRATOR) const uint INTEGRATOR = 0u;
layout(constant_id = SPEC_EMITTERS) const uint EMITTER_COUNT = 0u;
layout(constant_id = SPEC_ENV_WIDTH) const uint ENV_WIDTH = 0u;
layout(constant_id = SPEC_ENV_HEIGHT) const uint ENV_HEIGHT = 1u;
layout(constant_id = SPEC_TEXTURES) const bool HAS_TEXTURES = false;
layout(constant_id = SPEC_ALPHA) const uint ALPHA_BITS = 0u;
const bool HAS_ALPHA = (ALPHA_BITS & ALPHA_ON) != 0u;
layout(constant_id = SPEC_VERTEX_COLORS) const bool VERTEX_COLORS = false;
layout(constant_id = SPEC_MIS) const uint MIS_MODE = 0u;
layout(constant_id = SPEC_RR_DEPTH) const uint RR_DEPTH = 5u;
layout(constant_id = SPEC_MATERIAL_KINDS) const uint MATERIAL_KINDS = 255u;
layout(constant_id = SPEC_PACKET) const bool PACKET = false;
layout(constant_id = SPEC_WHITTED_SPLIT) const uint WHITTED_SPLIT = 0u;

#include "common/layout.glsl"
#include "common/ray.glsl"
#include "common/camera.glsl"
#include "common/rng.glsl"

uint g_nodes = 0u;
uint g_tests = 0u;
uint g_rays = 0u;
bool g_overflow = false;

#include "common/resume.glsl"
#include "common/colors.glsl"
#include "common/alpha.glsl"

#if HAS_TRIANGLES
bool intersect_triangle(uint i, Ray r, inout Hit h) {
    g_tests += 1u;
    uvec4 tri = triangle_at(i);
    float t, u, v;
    Ray rr = r;
    rr.tmax = h.t;
    // Closer wins; at equal t the lower index wins (same rule as Hit::closer in Rust).
    vec3 v0 = vertex_position(tri.x);
    vec3 v1 = vertex_position(tri.y);
    vec3 v2 = vertex_position(tri.z);
    bool hit = INTERSECT_MODE == 0u ? ray_triangle_watertight(rr, v0, v1, v2, t, u, v)
                                    : ray_triangle_fast(rr, v0, v1, v2, t, u, v);
    // A cut-out or blended pane may let the ray through (SPEC_ALPHA; common/alpha.glsl).
    if (hit && (t < h.t || i < h.prim) && (!HAS_ALPHA || alpha_meets(tri, i, r, u, v))) {
        h.t = t; h.prim = i; h.u = u; h.v = v;
        return true;
    }
    return false;
}
#endif

#if HAS_SPHERES
bool intersect_sphere(uint i, Ray r, inout Hit h) {
    g_tests += 1u;
    vec4 s = sphere_center_radius(i);
    float t;
    Ray rr = r;
    rr.tmax = h.t;
    if (ray_sphere(rr, s.xyz, s.w, t) && (t < h.t || params.triangle_count + i < h.prim)
        && (!HAS_ALPHA || sphere_alpha_meets(i, r))) {
        h.t = t; h.prim = params.triangle_count + i; h.u = 0.0; h.v = 0.0;
        return true;
    }
    return false;
}
#endif

// Primitive p of the global numbering (triangles first, then spheres), for trees.
bool intersect_prim(uint p, Ray r, inout Hit h) {
#if HAS_TRIANGLES && HAS_SPHERES
    if (p < params.triangle_count) return intersect_triangle(p, r, h);
    return intersect_sphere(p - params.triangle_count, r, h);
#elif HAS_TRIANGLES
    return intersect_triangle(p, r, h);
#else
    return intersect_sphere(p - params.triangle_count, r, h);
#endif
}

// The structure's traces: accel_closest and accel_any (accel/*.glsl), and their
// coherent forms (packets: BVHs only; the others trace coherent rays one by one).
#if defined(ACCEL_NONE)
#include "accel/none.glsl"
#elif defined(ACCEL_KDTREE)
#include "accel/kdtree.glsl"
#elif defined(ACCEL_BVH)
#include "accel/bvh.glsl"
#elif defined(ACCEL_GRID)
#include "accel/grid.glsl"
#elif defined(ACCEL_BVH4)
#include "accel/bvh4.glsl"
#elif defined(ACCEL_BVH8)
#include "accel/bvh8.glsl"
#elif defined(ACCEL_CWBVH)
#include "accel/cwbvh.glsl"
#elif defined(ACCEL_OCTREE)
#include "accel/octree.glsl"
#elif defined(ACCEL_RAYQUERY)
#include "accel/rayquery.glsl"
#endif

#if !defined(ACCEL_BVH)
bool accel_closest_coherent(Ray r, inout Hit h) { return accel_closest(r, h); }
bool accel_any_coherent(Ray r) { return accel_any(r); }
#endif

#ifdef HAS_INSTANCES
#include "common/instances.glsl"
#endif

// The scene's traces, which common/resume_trace.glsl wraps: with instances, the top
// level of common/instances.glsl over the structure's traces (no packets across
// instances: coherent rays trace one by one); else, and with the driver's structure,
// which has both levels in it, the structure's own.
#if defined(HAS_INSTANCES) && !defined(ACCEL_RAYQUERY)
bool scene_closest(Ray r, inout Hit h) { return inst_closest(r, h); }
bool scene_any(Ray r) { return inst_any(r); }
bool scene_closest_coherent(Ray r, inout Hit h) { return inst_closest(r, h); }
bool scene_any_coherent(Ray r) { return inst_any(r); }
#else
bool scene_closest(Ray r, inout Hit h) { return accel_closest(r, h); }
bool scene_any(Ray r) { return accel_any(r); }
bool scene_closest_coherent(Ray r, inout Hit h) { return accel_closest_coherent(r, h); }
bool scene_any_coherent(Ray r) { return accel_any_coherent(r); }
#endif

#include "common/resume_trace.glsl"

// The primitive number the AOV reports: that of the flattened scene with instances.
uint aov_prim(Hit h) {
#ifdef HAS_INSTANCES
    return inst_aov_prim(h);
#else
    return h.prim;
#endif
}

#include "common/sampling.glsl"
#include "common/textures.glsl"

// The hit point, its error bound and the geometric normal, without the shading frame.
void surface_point(Hit h, Ray r, out vec3 p, out vec3 err, out vec3 gn) {
    gn = vec3(0.0, 1.0, 0.0);
    p = vec3(0.0); err = vec3(0.0);
#if HAS_TRIANGLES
    if (h.prim < params.triangle_count) {
        uvec4 tri = triangle_at(h.prim);
        vec3 a = vertex_position(tri.x);
        vec3 b = vertex_position(tri.y);
        vec3 c = vertex_position(tri.z);
        triangle_point(a, b, c, h.u, h.v, p, err);
        gn = normalize(cross(b - a, c - a));
#ifdef HAS_INSTANCES
        vec3 sn = gn;
        inst_to_world(h, p, err, gn, sn);
#endif
        return;
    }
#endif
#if HAS_SPHERES
    vec4 s = sphere_center_radius(h.prim - params.triangle_count);
    vec3 rel;
    sphere_point(r.origin, r.dir, h.t, s.xyz, s.w, p, err, rel);
    gn = dot(rel, rel) > 0.0 ? normalize(rel) : -r.dir;
#endif
}

// Texture coordinates of the point of a sphere whose outward normal is n.
vec2 sphere_uv(vec3 n) {
    return vec2(0.5 + atan(n.x, -n.z) * (0.5 / PI), acos(clamp(n.y, -1.0, 1.0)) / PI);
}

// Shading frame at a hit: the point (recomputed on the surface) and its error bound
// for spawning rays, geometric normal (the triangle's winding, a sphere's outside),
// shading normal, material index, texture coordinates.
void surface(Hit h, Ray r, out vec3 p, out vec3 err, out vec3 gn, out vec3 sn, out uint mat, out vec2 uv) {
    gn = vec3(0.0, 1.0, 0.0); sn = gn; mat = 0u; uv = vec2(0.0);
    p = vec3(0.0); err = vec3(0.0);
#if HAS_TRIANGLES
    if (h.prim < params.triangle_count) {
        uvec4 tri = triangle_at(h.prim);
        Vertex a = vertex_at(tri.x);
        Vertex b = vertex_at(tri.y);
        Vertex c = vertex_at(tri.z);
        triangle_point(a.position.xyz, b.position.xyz, c.position.xyz, h.u, h.v, p, err);
        gn = normalize(cross(b.position.xyz - a.position.xyz, c.position.xyz - a.position.xyz));
        sn = gn;
        float w0 = 1.0 - h.u - h.v;
        if (dot(a.normal.xyz, a.normal.xyz) > 0.0 && dot(b.normal.xyz, b.normal.xyz) > 0.0
            && dot(c.normal.xyz, c.normal.xyz) > 0.0) {
            vec3 n = a.normal.xyz * w0 + b.normal.xyz * h.u + c.normal.xyz * h.v;
            if (dot(n, n) > 0.0) sn = normalize(n);
        }
        uv = vec2(a.position.w, a.normal.w) * w0 + vec2(b.position.w, b.normal.w) * h.u
             + vec2(c.position.w, c.normal.w) * h.v;
        mat = tri.w;
        if (HAS_TEXTURES && (MATERIAL_KINDS & (1u << MAT_PBR)) != 0u)
            sn = normal_mapped(mat, sn, uv, a.position.xyz, b.position.xyz, c.position.xyz,
                               vec2(a.position.w, a.normal.w), vec2(b.position.w, b.normal.w),
                               vec2(c.position.w, c.normal.w));
#ifdef HAS_INSTANCES
        inst_to_world(h, p, err, gn, sn);
#endif
        return;
    }
#endif
#if HAS_SPHERES
    Sphere s = sphere_at(h.prim - params.triangle_count);
    vec3 rel;
    sphere_point(r.origin, r.dir, h.t, s.center_radius.xyz, s.center_radius.w, p, err, rel);
    gn = dot(rel, rel) > 0.0 ? normalize(rel) : -r.dir;
    sn = gn;
    mat = s.material.x;
    uv = sphere_uv(gn);
#endif
}


#include "common/bsdf.glsl"
#include "common/path.glsl"
#include "common/whitted.glsl"
#if !defined(RAY_BATCH) && TRACE_ENTRY == INTEGRATOR_SPPM
#include "common/sppm.glsl"
#endif

// The benchmark's probe kernel (INTEGRATOR 2): the camera ray of sample 0 and, with
// DIFFUSE_PROBE, one cosine-distributed ray from its hit, on the side the camera ray
// came from; nothing else. It is the trace kernel stripped of shading: on llvmpipe
// both sides of every branch run for all 8 lanes (docs/lavapipe.md), so shading code
// would be paid by every ray whether it hit or not. The pixel records the hit (prim,
// depth, cost), radiance 1 where the camera ray hit (or, with DIFFUSE_PROBE, where
// the bounce escaped: ambient occlusion) and the background elsewhere.
void probe_main() {
    uint local;
    if (!job_begin(local)) return;
    uint slot = local - DISPATCH_BASE;
    uvec3 at = window_pixel(local);
    uint pixel = at.x;
    sample_start();
    Ray r;
    r.origin = params.cam_eye;
    r.dir = camera_ray_dir(at.y, at.z, 0.5, 0.5);
    r.tmin = 0.0;
    r.tmax = uintBitsToFloat(0x7f800000u);
    Hit h;
    h.t = r.tmax; h.prim = NO_PRIM; h.u = 0.0; h.v = 0.0;
    g_nodes = 0u; g_tests = 0u;
    bool hit = trace_closest_coherent(r, h);
    uvec3 cost = uvec3(hit ? aov_prim(h) : NO_PRIM, g_nodes, g_tests);
    uint rays = 1u;
    vec3 L = hit ? vec3(1.0) : params.background;
    vec3 n = vec3(0.0);
    if (DIFFUSE_PROBE && hit) {
        vec3 p, err, gn;
        surface_point(h, r, p, err, gn);
        n = dot(gn, r.dir) < 0.0 ? gn : -gn;
        uint rng = rng_init(pixel, 0u, params.seed);
        vec3 d = cosine_direction(n, rng_next(rng), rng_next(rng));
        Ray dr;
        dr.origin = offset_ray_origin(p, err, n, d); dr.dir = d;
        dr.tmin = 0.0; dr.tmax = uintBitsToFloat(0x7f800000u);
        Hit dh;
        dh.t = dr.tmax; dh.prim = NO_PRIM; dh.u = 0.0; dh.v = 0.0;
        rays = 2u;
        L = trace_closest(dr, dh) ? vec3(0.0) : params.background;
    }
    Pixel q;
    // A stopped sample holds none: the resume kernel's sweep finds the pixel by it.
    q.radiance = vec4(L, g_suspended ? 0.0 : 1.0);
    q.normal_depth = vec4(n, h.t);
    q.prim_cost = uvec4(cost, rays | (g_overflow ? OVERFLOW_FLAG : 0u));
    float y = luminance(L);
    q.albedo_m2 = vec4(0.0, 0.0, 0.0, y * y);
    job_end();
    pixels[slot] = q;
}

#ifdef RAY_BATCH
// The ray-batch kernel (RAY_BATCH, kernels rays_<family>_<geometry>; src/render/rays.rs):
// ray `slot` of the chunk from the ray buffer, its closest hit into its Pixel (layout
// in common/layout.glsl). One trace a job, resumed like the probe kernel's (specialised
// with INTEGRATOR 2, so the resume sweep finds a stopped ray by its zero count).
void batch_main() {
    uint local;
    if (!job_begin(local)) return;
    uint slot = local - DISPATCH_BASE;
    sample_start();
    vec4 origin_tmin, dir_tmax;
    ray_at(slot, origin_tmin, dir_tmax);
    Ray r;
    r.origin = origin_tmin.xyz;
    r.dir = dir_tmax.xyz;
    r.tmin = origin_tmin.w;
    r.tmax = dir_tmax.w;
    Hit h = no_hit(r);
    g_nodes = 0u; g_tests = 0u;
    bool hit = trace_closest(r, h);
    Pixel q;
    q.radiance = vec4(h.u, h.v, 0.0, g_suspended ? 0.0 : 1.0);
    q.normal_depth = vec4(0.0, 0.0, 0.0, h.t);
    q.prim_cost = uvec4(hit ? h.prim : NO_PRIM, g_nodes, g_tests, 1u | (g_overflow ? OVERFLOW_FLAG : 0u));
    q.albedo_m2 = vec4(0.0);
    job_end();
    pixels[slot] = q;
}

void main() {
    TREE_STEPS = DISPATCH_TRACE_STEPS;
    batch_main();
}
#else
// One integrator a module (TRACE_ENTRY, src/gpu/bindings.rs TRACE_ENTRIES): the others'
// code is not in it for the driver to compile and throw away.
void main() {
    TREE_STEPS = DISPATCH_TRACE_STEPS;
#if TRACE_ENTRY == INTEGRATOR_PATH
    path_main();
#elif TRACE_ENTRY == INTEGRATOR_PROBE
    probe_main();
#elif TRACE_ENTRY == INTEGRATOR_SPPM
    sppm_main();
#else
    whitted_main();
#endif
}
#endif
