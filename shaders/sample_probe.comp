#version 460
// Runs the path integrator's samplers on records written by tests/it/sampling.rs, which
// checks that each sampler's pdf is the pdf its evaluation reports, that pdfs
// integrate to 1, that no material reflects more than it receives, and that the
// environment sampler follows the map (chi-square).
//
// Push constant `range`: x mode, y records. Input records are two vec4, output
// records three vec4:
//   mode 0, BSDF sample: in (wo, material), (u, front); out (wi, pdf),
//           (weight, pdf that bsdf_eval reports at wi), (f at wi, ok | delta << 1 | transmit << 2)
//   mode 1, BSDF evaluation: in (wo, material), (wi, front); out (f, pdf), 0, 0
//   mode 2, environment sample: in (u1, u2, unused), unused; out (direction, pdf),
//           (env_pdf at the direction, the direction's cell x and y, the sampled cell
//           y * width + x), (radiance, unused)
//   mode 3, material decode (`material_at`): in (part, 0, 0, material), unused; out,
//           uint words as their float bits:
//           part 0: (albedo, kind), (specular, shininess), (emission, emission_map)
//           part 1: (absorption, ior), (eta, alpha), (k, flags)
//           part 2: (f0, metallic), (spec_weight, 0, 0, 0), 0
//   mode 4, light decode (`light_at`): in (0, 0, 0, light), unused; out
//           (position or direction, 1 point | 0 directional), (radiance, 0), 0
// The shading normal is +z; `front` is 1.0 when wo is on the geometric normal's side.
#extension GL_GOOGLE_include_directive : require
layout(local_size_x = 64) in;
#define HAS_TRIANGLES 0
#define HAS_SPHERES 0
layout(constant_id = SPEC_ENV_WIDTH) const uint ENV_WIDTH = 1u;
layout(constant_id = SPEC_ENV_HEIGHT) const uint ENV_HEIGHT = 1u;
layout(constant_id = SPEC_MATERIAL_KINDS) const uint MATERIAL_KINDS = 255u;
#include "common/layout.glsl"


#include "common/bsdf.glsl"
#include "common/envmap.glsl"

layout(push_constant) uniform ProbeBlock {
    uvec4 range;
    uvec4 unused;
} probe;

layout(std430, set = 0, binding = BINDING_ACCEL_NODES) readonly buffer ProbeIn { vec4 probe_in[]; };
layout(std430, set = 0, binding = BINDING_ACCEL_INDICES) writeonly buffer ProbeOut { vec4 probe_out[]; };

void main() {
    uint i = gl_GlobalInvocationID.x;
    if (i >= probe.range.y) return;
    vec4 a = probe_in[2u * i];
    vec4 b = probe_in[2u * i + 1u];
    vec3 n = vec3(0.0, 0.0, 1.0);
    vec4 o0 = vec4(0.0), o1 = vec4(0.0), o2 = vec4(0.0);
    if (probe.range.x == 0u) {
        Material m = material_at(uint(a.w));
        vec3 wi, weight;
        float pdf;
        bool delta, transmit;
        bool ok = bsdf_sample(m, n, a.xyz, b.w > 0.5, b.xyz, wi, weight, pdf, delta, transmit);
        float epdf;
        vec3 f = bsdf_eval(m, n, a.xyz, wi, b.w > 0.5, epdf);
        o0 = vec4(wi, pdf);
        o1 = vec4(weight, epdf);
        o2 = vec4(f, float(uint(ok) | uint(delta) << 1u | uint(transmit) << 2u));
    } else if (probe.range.x == 1u) {
        Material m = material_at(uint(a.w));
        float pdf;
        vec3 f = bsdf_eval(m, n, a.xyz, b.xyz, b.w > 0.5, pdf);
        o0 = vec4(f, pdf);
    } else if (probe.range.x == 3u) {
        Material m = material_at(uint(a.w));
        if (a.x == 0.0) {
            o0 = vec4(m.albedo, uintBitsToFloat(m.kind));
            o1 = vec4(m.specular, m.shininess);
            o2 = vec4(m.emission, uintBitsToFloat(m.emission_map));
        } else if (a.x == 1.0) {
            o0 = vec4(m.absorption, m.ior);
            o1 = vec4(m.eta, m.alpha);
            o2 = vec4(m.k, uintBitsToFloat(m.flags));
        } else {
            o0 = vec4(m.f0, m.metallic);
            o1 = vec4(m.spec_weight, 0.0, 0.0, 0.0);
        }
    } else if (probe.range.x == 4u) {
        vec3 at, radiance;
        bool point;
        light_at(uint(a.w), at, point, radiance);
        o0 = vec4(at, point ? 1.0 : 0.0);
        o1 = vec4(radiance, 0.0);
    } else {
        vec3 d;
        float pdf;
        uvec2 cell;
        vec3 le = env_sample(a.x, a.y, d, pdf, cell);
        uvec2 c = env_cell(env_dir_to_uv(d));
        o0 = vec4(d, pdf);
        o1 = vec4(env_pdf(d), float(c.x), float(c.y), float(cell.y * ENV_WIDTH + cell.x));
        o2 = vec4(le, 0.0);
    }
    probe_out[3u * i] = o0;
    probe_out[3u * i + 1u] = o1;
    probe_out[3u * i + 2u] = o2;
}
