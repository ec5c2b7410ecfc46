// The driver's own structure (`--accel rayquery`, src/accel/rayquery.rs): a TLAS built
// through VK_KHR_acceleration_structure, traversed by the driver inside
// rayQueryProceedEXT. Triangles are opaque geometry, committed by the driver with its
// own ray/triangle test (its watertightness, not arbor's); spheres are box geometry
// whose candidates this file intersects with arbor's ray_sphere and commits. Each
// loop iteration is one candidate box, at most TREE_STEPS of them per trace (the
// pixel is flagged beyond). The driver cannot report nodes visited or triangles
// tested, so g_nodes and g_tests stay 0 and the host reports them as unknown.
//
// Hit numbering is that of the other kernels: an instance's custom index is its entry
// in the two-level records (common/instances.glsl), whose word 6.z is the entry's
// first stored triangle; the scene's own primitives are the last entry (or the only
// instance, custom index 0, first triangle 0, without instancing); a sphere is
// params.triangle_count + its box's index.
#extension GL_EXT_ray_query : require

layout(set = 0, binding = BINDING_TLAS) uniform accelerationStructureEXT tlas;

#ifdef HAS_INSTANCES
#include "common/accel_texels.glsl"
#endif

// Largest finite tmax handed to the driver (rays are unbounded as +inf elsewhere).
const float RQ_TMAX = 3.0e38;

// The stored number of the first triangle of instance custom index e.
uint rq_first_triangle(uint e) {
#ifdef HAS_INSTANCES
    uint records = texelFetch(accel_node_texels, 0).z;
    return texelFetch(accel_node_texels, int(records + e * INST_ENTRY_TEXELS + 6u)).z;
#else
    return 0u;
#endif
}

bool rq_trace(Ray r, inout Hit h, bool any_hit) {
    rayQueryEXT q;
    // With cut-outs or blended panes every triangle is a candidate this loop tests
    // (common/alpha.glsl) and confirms; otherwise the driver commits them itself.
    uint flags = (HAS_ALPHA ? gl_RayFlagsNoOpaqueEXT : gl_RayFlagsOpaqueEXT)
        | (any_hit ? gl_RayFlagsTerminateOnFirstHitEXT : 0u);
    rayQueryInitializeEXT(q, tlas, flags, 0xffu, r.origin, r.tmin, r.dir, min(h.t, RQ_TMAX));
    uint rq_steps = 0u;
    bool more = true;
    while (rq_steps < TREE_STEPS) {
        more = rayQueryProceedEXT(q);
        if (!more) break;
        rq_steps += 1u;
#if HAS_TRIANGLES
        if (HAS_ALPHA && rayQueryGetIntersectionTypeEXT(q, false) == gl_RayQueryCandidateIntersectionTriangleEXT) {
            uint e = uint(rayQueryGetIntersectionInstanceCustomIndexEXT(q, false));
            uint p = rq_first_triangle(e) + uint(rayQueryGetIntersectionPrimitiveIndexEXT(q, false));
            vec2 b = rayQueryGetIntersectionBarycentricsEXT(q, false);
            if (alpha_meets(triangle_at(p), p, r, b.x, b.y)) rayQueryConfirmIntersectionEXT(q);
        }
#endif
#if HAS_SPHERES
        if (rayQueryGetIntersectionTypeEXT(q, false) == gl_RayQueryCandidateIntersectionAABBEXT) {
            uint j = rayQueryGetIntersectionPrimitiveIndexEXT(q, false);
            vec4 s = sphere_center_radius(j);
            Ray rr = r;
            rr.tmax = rayQueryGetIntersectionTypeEXT(q, true) == gl_RayQueryCommittedIntersectionNoneEXT
                ? min(h.t, RQ_TMAX) : rayQueryGetIntersectionTEXT(q, true);
            float t;
            if (ray_sphere(rr, s.xyz, s.w, t) && t >= r.tmin && (!HAS_ALPHA || sphere_alpha_meets(j, r)))
                rayQueryGenerateIntersectionEXT(q, t);
        }
#endif
    }
    if (more) {
        // Out of steps with candidates left: the result would be wrong.
        rayQueryTerminateEXT(q);
        g_overflow = true;
    }
    uint kind = rayQueryGetIntersectionTypeEXT(q, true);
    if (kind == gl_RayQueryCommittedIntersectionNoneEXT) return false;
    uint e = uint(rayQueryGetIntersectionInstanceCustomIndexEXT(q, true));
    uint p = uint(rayQueryGetIntersectionPrimitiveIndexEXT(q, true));
    h.t = rayQueryGetIntersectionTEXT(q, true);
    if (kind == gl_RayQueryCommittedIntersectionTriangleEXT) {
        vec2 b = rayQueryGetIntersectionBarycentricsEXT(q, true);
        h.prim = rq_first_triangle(e) + p;
        h.u = b.x;
        h.v = b.y;
    } else {
        h.prim = params.triangle_count + p;
        h.u = 0.0;
        h.v = 0.0;
    }
#ifdef HAS_INSTANCES
    h.inst = e;
#endif
    return true;
}

bool accel_closest(Ray r, inout Hit h) { return rq_trace(r, h, false); }

bool accel_any(Ray r) {
    Hit h;
    h.t = r.tmax; h.prim = NO_PRIM; h.u = 0.0; h.v = 0.0;
#ifdef HAS_INSTANCES
    h.inst = 0u;
#endif
    return rq_trace(r, h, true);
}
