#version 460
// Copies every field of every struct in common/layout.glsl back out as raw words,
// in Rust declaration order, so tests/it/gpu_layout.rs can prove Rust and GLSL agree.
#extension GL_GOOGLE_include_directive : require
layout(local_size_x = 1) in;
#define HAS_TRIANGLES 1
#define HAS_SPHERES 1
#define RAY_BATCH 1
#include "common/layout.glsl"


layout(std430, set = 0, binding = BINDING_ACCEL_NODES) buffer ProbeOut { uint words[]; };

void w4(inout uint o, uvec4 v) { words[o] = v.x; words[o + 1u] = v.y; words[o + 2u] = v.z; words[o + 3u] = v.w; o += 4u; }
void f4(inout uint o, vec4 v) { w4(o, floatBitsToUint(v)); }
void w1(inout uint o, uint v) { words[o] = v; o += 1u; }
void f1(inout uint o, float v) { w1(o, floatBitsToUint(v)); }
void f3(inout uint o, vec3 v) { f1(o, v.x); f1(o, v.y); f1(o, v.z); }

void main() {
    uint o = 0u;
    // GpuParams, every field in declaration order
    f3(o, params.cam_eye); f1(o, params.tan_half_fov); f3(o, params.cam_right); f1(o, params.aspect);
    f3(o, params.cam_up); f1(o, params.photon_unit); f3(o, params.cam_forward); f1(o, params.photon_radius);
    f3(o, params.scene_min); w1(o, params.photon_light_table); f3(o, params.scene_max); w1(o, params.photon_lights);
    w1(o, params.width); w1(o, params.height); w1(o, params.triangle_count); w1(o, params.sphere_count);
    w1(o, params.light_count); w1(o, params.material_count); w1(o, params.seed); w1(o, params.photon_count);
    f3(o, params.background); f1(o, params.ambient);
    w1(o, params.emitter_table); w1(o, params.texture_table); w1(o, params.env_texel_table); w1(o, params.env_distribution_table);
    f1(o, params.env_intensity); f1(o, params.env_rotation); f1(o, params.emitter_power); w1(o, params.alpha_table);
    w1(o, params.vertex_color_table); w1(o, params.spare0); w1(o, params.spare1); w1(o, params.spare2);
    // GpuDispatch (the pixel buffer's header)
    w4(o, dispatch_range); w4(o, dispatch_chunk); w4(o, dispatch_window); w4(o, dispatch_limits);
    // GpuVertex[0..2]
    for (uint k = 0u; k < 2u; k++) { f4(o, vertex_at(k).position); f4(o, vertex_at(k).normal); }
    // GpuTriangle[0..2]
    for (uint k = 0u; k < 2u; k++) { w4(o, triangle_at(k)); }
    // GpuSphere[0..2]
    for (uint k = 0u; k < 2u; k++) { f4(o, sphere_center_radius(k)); w4(o, sphere_at(k).material); }
    // shading rows: one GpuMaterial + one GpuLight
    for (uint k = 0u; k < MATERIAL_ROWS + LIGHT_ROWS; k++) { f4(o, shading_row(k)); }
    // GpuPixel[0..2] (read)
    for (uint k = 0u; k < 2u; k++) { f4(o, pixels[k].radiance); f4(o, pixels[k].normal_depth); w4(o, pixels[k].prim_cost); f4(o, pixels[k].albedo_m2); }
    // GpuRay[0..2]
    for (uint k = 0u; k < 2u; k++) { vec4 a, b; ray_at(k, a, b); f4(o, a); f4(o, b); }
}
