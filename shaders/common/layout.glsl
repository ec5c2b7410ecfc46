// std430 / std140 mirror of src/accel/gpu_layout.rs. Byte offsets in comments must
// match the Rust side; tests/it/gpu_layout.rs checks it on the device.
#ifndef ARBOR_LAYOUT_GLSL
#define ARBOR_LAYOUT_GLSL

struct Vertex {
    vec4 position;   // 0..12 position, 12..16 texture u
    vec4 normal;     // 16..28 normal (zero: none), 28..32 texture v
};                   // 32 bytes

struct Sphere {
    vec4 center_radius; // 0..12 centre, 12..16 radius
    uvec4 material;     // 16..20 material index
};                      // 32 bytes

struct Pixel {
    vec4 radiance;      // 0..12 summed radiance, 12..16 sample count
    vec4 normal_depth;  // 16..28 normal, 28..32 depth
    uvec4 prim_cost;    // 32..36 prim, 36..40 nodes visited, 40..44 prims tested, 44..48 rays
    vec4 albedo_m2;     // 48..60 albedo at the first hit, 60..64 summed squared luminance
};                      // 64 bytes

// Material = 4 vec4 rows of the shading buffer:
//   row 0: rgb colour (conductor: tint, or F0 with MAT_FLAG_SCHLICK), a = kind | emission
//          texture + 1 << MAT_MAP_SHIFT (uint bits)
//   row 1: rgb specular (Phong) or eta (conductor), a = shininess (Phong) or GGX
//          alpha = roughness^2 (conductor, dielectric); metallic-roughness (MAT_PBR):
//          metallic, specular weight, normal-map scale, roughness
//   row 2: rgb emission, a = ior (MAT_PBR: uint bits, metallic-roughness texture + 1
//          | normal texture + 1 << MAT_MAP_SHIFT)
//   row 3: rgb absorption (glass, dielectric), k (conductor) or the dielectric
//          layer's F0 (MAT_PBR), a = flags (uint
//          bits): MAT_FLAG_TWO_SIDED, MAT_FLAG_SCHLICK, texture index + 1 from bit
//          MAT_TEXTURE_SHIFT (0: none)
// Light = 2 vec4 rows, after all materials:
//   row 0: xyz position (w = 1) or travel direction (w = 0)
//   row 1: rgb radiance / intensity
#define MATERIAL_ROWS 4
#define LIGHT_ROWS 2
// The MAT_* kind codes come from src/gpu/bindings.rs.

layout(std140, set = 0, binding = BINDING_PARAMS) uniform ParamsBlock {
    vec4 cam_eye;      // 0   xyz eye, w tan(vfov/2)
    vec4 cam_right;    // 16  xyz right, w aspect
    vec4 cam_up;       // 32
    vec4 cam_forward;  // 48
    vec4 scene_min;    // 64
    vec4 scene_max;    // 80
    uvec4 dims;        // 96  width, height, triangles, spheres
    uvec4 counts;      // 112 lights (the trace loop uses SPEC_LIGHTS), materials, seed, flags
    vec4 background;   // 128 rgb, a ambient factor
    uvec4 tables;      // 144 path integrator: shading rows of the emitters, textures,
                       //     environment texels, environment distribution
    vec4 env;          // 160 environment intensity, rotation (radians), total emitter power
} params;

#if HAS_TRIANGLES
// Vertices and triangles are uniform texel buffers (RGBA32UI views of the same bytes):
// on llvmpipe a texel fetch is one vector gather where a storage-buffer load is a loop
// over the lanes (docs/lavapipe.md). A vertex is two texels.
layout(set = 0, binding = BINDING_VERTICES) uniform usamplerBuffer vertex_texels;
layout(set = 0, binding = BINDING_TRIANGLES) uniform usamplerBuffer triangle_texels;
uvec4 triangle_at(uint i) { return texelFetch(triangle_texels, int(i)); }
vec3 vertex_position(uint i) { return uintBitsToFloat(texelFetch(vertex_texels, int(2u * i)).xyz); }
Vertex vertex_at(uint i) {
    Vertex v;
    v.position = uintBitsToFloat(texelFetch(vertex_texels, int(2u * i)));
    v.normal = uintBitsToFloat(texelFetch(vertex_texels, int(2u * i + 1u)));
    return v;
}
#endif
#if HAS_SPHERES
// Spheres: a texel buffer, two texels each.
layout(set = 0, binding = BINDING_SPHERES) uniform usamplerBuffer sphere_texels;
vec4 sphere_center_radius(uint i) { return uintBitsToFloat(texelFetch(sphere_texels, int(2u * i))); }
Sphere sphere_at(uint i) {
    Sphere s;
    s.center_radius = sphere_center_radius(i);
    s.material = texelFetch(sphere_texels, int(2u * i + 1u));
    return s;
}
#endif
#ifdef RAY_BATCH
// The rays of a ray batch (GpuRay), a texel buffer, two texels each:
//   texel 2i:     0..12 origin, 12..16 tmin
//   texel 2i + 1: 16..28 direction, 28..32 tmax
// The kernel writes each ray's hit into its Pixel: radiance (u, v, 0, 1 when complete),
// normal_depth.w t, prim_cost (prim, nodes, tests, 1 | OVERFLOW_FLAG).
layout(set = 0, binding = BINDING_RAYS) uniform usamplerBuffer ray_texels;
void ray_at(uint i, out vec4 origin_tmin, out vec4 dir_tmax) {
    origin_tmin = uintBitsToFloat(texelFetch(ray_texels, int(2u * i)));
    dir_tmax = uintBitsToFloat(texelFetch(ray_texels, int(2u * i + 1u)));
}
#endif
// The shading rows (materials, lights, the path integrator's tables), a texel buffer.
layout(set = 0, binding = BINDING_SHADING) uniform usamplerBuffer shading_texels;
vec4 shading_row(uint k) { return uintBitsToFloat(texelFetch(shading_texels, int(k))); }
// Word k (float or uint bits) of a section of the shading buffer, 4 words a row.
float shading_float(uint base, uint k) { return shading_row(base + (k >> 2u))[k & 3u]; }
uint shading_word(uint base, uint k) { return floatBitsToUint(shading_row(base + (k >> 2u))[k & 3u]); }
// The pixel buffer opens with the dispatch header (`GpuDispatch`), which the host
// writes before each dispatch (vkCmdUpdateBuffer). It is storage, not push constants,
// because lavapipe compiles a shader again, at every dispatch, for the values of push
// constants and uniforms that its branches and loops depend on (docs/kernels.md, "Per-dispatch
// values live in storage").
layout(std430, set = 0, binding = BINDING_PIXELS) buffer PixelBuffer {
    uvec4 dispatch_range;  // 0  first, count, sample_begin, sample_end
    uvec4 dispatch_chunk;  // 16 base, resumed, pass, counter (DispatchChunk; copied back)
    uvec4 dispatch_window; // 32 window_left, window_top, window_width, zero_sample
    uvec4 dispatch_limits; // 48 trace_steps (TREE_STEPS in trace.comp), then 0, 0, 0
    Pixel pixels[];        // 64
};

// The header's words by name (`GpuDispatch` and `DispatchChunk` in
// src/accel/gpu_layout.rs, whose fields these are).
#define DISPATCH_FIRST dispatch_range.x         // first pixel (a resume list pass: first job)
#define DISPATCH_COUNT dispatch_range.y         // pixels (or jobs)
#define DISPATCH_SAMPLE_BEGIN dispatch_range.z  // first sample
#define DISPATCH_SAMPLE_END dispatch_range.w    // end sample (exclusive)
#define DISPATCH_BASE dispatch_chunk.x          // first pixel held by this buffer
#define DISPATCH_RESUMED dispatch_chunk.y       // 1: a resumed part
#define DISPATCH_PASS dispatch_chunk.z          // PASS_TRACE or a resume pass
#define DISPATCH_COUNTER dispatch_chunk.w       // samples stopped / jobs handed on (copied back)
#define DISPATCH_WINDOW_LEFT dispatch_window.x
#define DISPATCH_WINDOW_TOP dispatch_window.y
#define DISPATCH_WINDOW_WIDTH dispatch_window.z
#define DISPATCH_ZERO_SAMPLE dispatch_window.w  // the sample at which pixels start from zero
#define DISPATCH_TRACE_STEPS dispatch_limits.x  // steps one trace may take

// The pixel of the full image that window-relative pixel `local` is (the random
// numbers are keyed by it, so a crop renders exactly what the whole image would), and
// its column and row.
uvec3 window_pixel(uint local) {
    uint i = DISPATCH_WINDOW_LEFT + local % DISPATCH_WINDOW_WIDTH;
    uint j = DISPATCH_WINDOW_TOP + local / DISPATCH_WINDOW_WIDTH;
    return uvec3(j * params.dims.x + i, i, j);
}

// The pixel's state before this dispatch's samples: zero at the window's first sample,
// else what earlier dispatches (or a resumed part, uploaded by the host) left.
Pixel pixel_start(uint slot) {
    if (DISPATCH_RESUMED == 0u && DISPATCH_PASS == PASS_TRACE && DISPATCH_SAMPLE_BEGIN == DISPATCH_ZERO_SAMPLE) {
        Pixel p;
        p.radiance = vec4(0.0);
        p.normal_depth = vec4(0.0, 0.0, 0.0, uintBitsToFloat(0x7f800000u));
        p.prim_cost = uvec4(0xffffffffu, 0u, 0u, 0u);
        p.albedo_m2 = vec4(0.0);
        return p;
    }
    return pixels[slot];
}

// The first sample of this dispatch the pixel lacks. A resumed pixel (DISPATCH_RESUMED
// set), and one the resume kernel continues (DISPATCH_PASS, common/resume.glsl),
// holds samples from the window's first one up to its count already.
uint sample_begin(Pixel p) {
    if (DISPATCH_RESUMED == 0u && DISPATCH_PASS == PASS_TRACE) return DISPATCH_SAMPLE_BEGIN;
    return max(DISPATCH_SAMPLE_BEGIN, DISPATCH_ZERO_SAMPLE + uint(p.radiance.w));
}

#endif
