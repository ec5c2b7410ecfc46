#version 460
// Runs the robustness helpers of common/ray.glsl on records written by
// tests/it/robustness.rs, which checks the results against src/math bit for bit.
// Input record (5 vec4): p0 + u, p1 + v, p2 + unused, n + unused, w + unused.
// Output record (12 floats): triangle_point p and err, offset_ray_origin(p, err, n, w),
// edge_function(p0.x, p1.y, p1.x, p0.y), next_float_up(u), next_float_down(v).
#extension GL_GOOGLE_include_directive : require
layout(local_size_x = 64) in;
#include "common/ray.glsl"

layout(push_constant) uniform DispatchBlock {
    uvec4 range; // y = records
    uvec4 chunk;
} dispatch_info;

layout(std430, set = 0, binding = BINDING_ACCEL_NODES) readonly buffer ProbeIn { vec4 probe_in[]; };
layout(std430, set = 0, binding = BINDING_ACCEL_INDICES) writeonly buffer ProbeOut { float probe_out[]; };

void main() {
    uint i = gl_GlobalInvocationID.x;
    if (i >= dispatch_info.range.y) return;
    vec4 a = probe_in[5u * i];
    vec4 b = probe_in[5u * i + 1u];
    vec4 c = probe_in[5u * i + 2u];
    vec3 n = probe_in[5u * i + 3u].xyz;
    vec3 w = probe_in[5u * i + 4u].xyz;
    vec3 p, err;
    triangle_point(a.xyz, b.xyz, c.xyz, a.w, b.w, p, err);
    vec3 o = offset_ray_origin(p, err, n, w);
    float e = edge_function(a.x, b.y, b.x, a.y);
    float outs[12] = float[12](p.x, p.y, p.z, err.x, err.y, err.z, o.x, o.y, o.z, e, next_float_up(a.w), next_float_down(b.w));
    for (uint k = 0u; k < 12u; k++) probe_out[12u * i + k] = outs[k];
}
