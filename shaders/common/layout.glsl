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

// Material and light records: rows of the shading buffer whose words are named in
// src/gpu/bindings.rs (MAT_W_*, LIGHT_W_*: the table of which kind uses which word);
// read below (`mat_row`, `mat_word`, `light_at`) and in common/bsdf.glsl (`material_at`).

layout(std140, set = 0, binding = BINDING_PARAMS) uniform ParamsBlock {
    vec3 cam_eye;                // 0
    float tan_half_fov;          // 12  tan(vfov / 2)
    vec3 cam_right;              // 16  unit
    float aspect;                // 28  width / height
    vec3 cam_up;                 // 32  unit
    float photon_unit;           // 44  SPPM: the flux of one unit of a deposit
    vec3 cam_forward;            // 48  unit
    float photon_radius;         // 60  SPPM: the initial radius (0: footprint)
    vec3 scene_min;              // 64  the scene box
    uint photon_light_table;     // 76  SPPM: the photon light table's first row
    vec3 scene_max;              // 80
    uint photon_lights;          // 92  SPPM: its rows
    uint width;                  // 96  the whole image
    uint height;                 // 100
    uint triangle_count;         // 104 primitives 0.. are triangles, spheres follow
    uint sphere_count;           // 108
    uint light_count;            // 112 (the light loops use SPEC_LIGHTS)
    uint material_count;         // 116 the light records follow the materials
    uint seed;                   // 120
    uint photon_count;           // 124 SPPM: photons per iteration
    vec3 background;             // 128 radiance of a ray that leaves the scene
    float ambient;               // 140 Whitted's ambient factor
    uint emitter_table;          // 144 first shading rows of the path integrator's tables:
    uint texture_table;          // 148   area lights by power, textures,
    uint env_texel_table;        // 152   environment texels,
    uint env_distribution_table; // 156   environment distribution
    float env_intensity;         // 160
    float env_rotation;          // 164 about +y, radians
    float emitter_power;         // 168 the emitter table's total
    uint alpha_table;            // 172 cut-outs and blended panes (common/alpha.glsl)
    uint vertex_color_table;     // 176 vertex colours (common/colors.glsl)
    uint spare0;                 // 180 unused
    uint spare1;                 // 184
    uint spare2;                 // 188
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

// Row `row` and word `w` (MAT_W_*) of material `mat`'s record.
vec4 mat_row(uint mat, uint row) { return shading_row(mat * MATERIAL_ROWS + row); }
float mat_word(uint mat, uint w) { return shading_float(mat * MATERIAL_ROWS, w); }
uint mat_bits(uint mat, uint w) { return shading_word(mat * MATERIAL_ROWS, w); }
// A record's word `w` and the three words from `w` (a _RGB word opens a row), from its
// rows read once into `rec`.
#define REC_WORD(rec, w) (rec)[(w) >> 2][(w) & 3]
#define REC_BITS(rec, w) floatBitsToUint(REC_WORD(rec, w))
#define REC_RGB(rec, w) (rec)[(w) >> 2].rgb
#if (MAT_W_COLOR_RGB & 3) != 0 || (MAT_W_SPECULAR_RGB & 3) != 0 || (MAT_W_ETA_RGB & 3) != 0 || (MAT_W_EMISSION_RGB & 3) != 0 || (MAT_W_ABSORPTION_RGB & 3) != 0 || (MAT_W_K_RGB & 3) != 0 || (MAT_W_F0_RGB & 3) != 0 || (LIGHT_W_POSITION_RGB & 3) != 0 || (LIGHT_W_RADIANCE_RGB & 3) != 0
#error "a _RGB record word must open a row"
#endif
#if MATERIAL_ROWS != 4 || LIGHT_ROWS != 2
#error "material_at reads four rows, light_at two"
#endif

// Point or directional light `l` (its record follows the materials'): the position
// (point) or the direction the light travels (directional), and the intensity (point)
// or radiance (directional).
void light_at(uint l, out vec3 position_or_direction, out bool point, out vec3 radiance) {
    uint base = params.material_count * MATERIAL_ROWS + l * LIGHT_ROWS;
    vec4 rec[LIGHT_ROWS];
    rec[0] = shading_row(base);
    rec[1] = shading_row(base + 1u);
    position_or_direction = REC_RGB(rec, LIGHT_W_POSITION_RGB);
    point = REC_WORD(rec, LIGHT_W_IS_POINT) > 0.5;
    radiance = REC_RGB(rec, LIGHT_W_RADIANCE_RGB);
}
// The pixel buffer opens with the dispatch header (`GpuDispatch`), which the host
// writes before each dispatch (vkCmdUpdateBuffer). It is storage, not push constants,
// because lavapipe compiles a shader again, at every dispatch, for the values of push
// constants and uniforms that its branches and loops depend on (docs/kernels.md, "Per-dispatch
// values live in storage").
layout(std430, set = 0, binding = BINDING_PIXELS) buffer PixelBuffer {
    uvec4 dispatch_range;  // 0  first, count, sample_begin, sample_end
    uvec4 dispatch_chunk;  // 16 base, resumed, pass, counter (DispatchChunk; copied back)
    uvec4 dispatch_window; // 32 window_left, window_top, window_width, zero_sample
    uvec4 dispatch_limits; // 48 trace_steps (TREE_STEPS in trace.comp), 0, map_size, map_buckets
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
#define DISPATCH_MAP_SIZE dispatch_limits.z     // SPPM: points in the grid, or tree nodes
#define DISPATCH_MAP_BUCKETS dispatch_limits.w  // SPPM: the grid's buckets

// The pixel of the full image that window-relative pixel `local` is (the random
// numbers are keyed by it, so a crop renders exactly what the whole image would), and
// its column and row.
uvec3 window_pixel(uint local) {
    uint i = DISPATCH_WINDOW_LEFT + local % DISPATCH_WINDOW_WIDTH;
    uint j = DISPATCH_WINDOW_TOP + local / DISPATCH_WINDOW_WIDTH;
    return uvec3(j * params.width + i, i, j);
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
