#version 460
// Primitive boxes (as prim::bounds) and the centroid box of the scene, reduced per
// thread (ITEMS primitives each, consecutive threads on consecutive primitives), per
// workgroup, then with atomics on order-preserving uints. Push: n, a = triangles.
// Variants build_bounds_{tris,spheres,all} declare only the geometry they read.
#define USE_HEADER 1
#define USE_PRIM_BOUNDS 1
#include "build/common.glsl"

layout(local_size_x = BUILD_GROUP) in;

#if HAS_TRIANGLES
layout(std430, set = 0, binding = BINDING_VERTICES) readonly buffer BuildVertices { vec4 geo_vertices[]; }; // Vertex: position, normal
layout(std430, set = 0, binding = BINDING_TRIANGLES) readonly buffer BuildTriangles { uvec4 geo_triangles[]; };
#endif
#if HAS_SPHERES
layout(std430, set = 0, binding = BINDING_SPHERES) readonly buffer BuildSpheres { vec4 geo_spheres[]; }; // Sphere: centre + radius, material
#endif

shared uint s_min[3][BUILD_GROUP];
shared uint s_max[3][BUILD_GROUP];

// Primitives per thread (src/gpu/bindings.rs): fewer workgroups, so fewer barriers and
// atomics.
const uint ITEMS = BUILD_BOUNDS_ITEMS;

void main() {
    uint lid = gl_LocalInvocationID.x;
    uvec3 cmin = uvec3(NONE);
    uvec3 cmax = uvec3(0u);
    for (uint item = 0u; item < ITEMS; ++item) {
        uint i = (group_index() * ITEMS + item) * BUILD_GROUP + lid;
        if (i >= pc.n) continue;
        vec3 lo = vec3(0.0);
        vec3 hi = vec3(0.0);
#if HAS_TRIANGLES
        if (i < pc.a) {
            uvec4 t = geo_triangles[i];
            vec3 p0 = geo_vertices[2u * t.x].xyz;
            vec3 p1 = geo_vertices[2u * t.y].xyz;
            vec3 p2 = geo_vertices[2u * t.z].xyz;
            lo = min(min(p0, p1), p2);
            hi = max(max(p0, p1), p2);
        }
#endif
#if HAS_SPHERES
        if (i >= pc.a) {
            vec4 s = geo_spheres[2u * (i - pc.a)];
            precise vec3 l = s.xyz - vec3(s.w);
            precise vec3 h = s.xyz + vec3(s.w);
            lo = l;
            hi = h;
        }
#endif
        prim_bounds[2u * i] = vec4(lo, 0.0);
        prim_bounds[2u * i + 1u] = vec4(hi, 0.0);
        precise vec3 c = (lo + hi) * 0.5;
        uvec3 o = uvec3(float_order(c.x), float_order(c.y), float_order(c.z));
        cmin = min(cmin, o);
        cmax = max(cmax, o);
    }
    for (uint k = 0u; k < 3u; ++k) {
        s_min[k][lid] = cmin[k];
        s_max[k][lid] = cmax[k];
    }
    barrier();
    for (uint stride = BUILD_GROUP / 2u; stride > 0u; stride >>= 1u) {
        if (lid < stride) {
            for (uint k = 0u; k < 3u; ++k) {
                s_min[k][lid] = min(s_min[k][lid], s_min[k][lid + stride]);
                s_max[k][lid] = max(s_max[k][lid], s_max[k][lid + stride]);
            }
        }
        barrier();
    }
    if (lid < 3u) {
        atomicMin(hdr[BUILD_HDR_CMIN + lid], s_min[lid][0]);
        atomicMax(hdr[BUILD_HDR_CMAX + lid], s_max[lid][0]);
    }
}
