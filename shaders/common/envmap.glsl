// Environment map lookup and importance sampling (the path integrator and
// shaders/sample_probe.comp): texels and the piecewise-constant distribution live in
// the shading buffer (sections in common/path.glsl). Needs ENV_WIDTH, ENV_HEIGHT.
#ifndef ARBOR_ENVMAP_GLSL
#define ARBOR_ENVMAP_GLSL

#include "common/sampling.glsl"

float shading_float(uint base, uint k) {
    return shading[base + (k >> 2u)][k & 3u];
}

uint shading_word(uint base, uint k) {
    return floatBitsToUint(shading[base + (k >> 2u)][k & 3u]);
}

// Largest i in [0, n) with cdf(i) <= u, for the n + 1 non-decreasing floats of a CDF
// at float index `first` of section `base` (cdf(0) = 0).
uint cdf_search(uint base, uint first, uint n, float u) {
    uint lo = 0u;
    uint hi = n;
    for (uint k = 0u; k < 32u && hi - lo > 1u; k++) {
        uint mid = (lo + hi) >> 1u;
        if (shading_float(base, first + mid) <= u) lo = mid; else hi = mid;
    }
    return lo;
}

// --- environment ---------------------------------------------------------------

// The map's direction convention (render::envdist): u = phi / 2 pi, v = theta / pi
// with theta from +y; params.env.y is the rotation about +y in radians.
vec2 env_dir_to_uv(vec3 d) {
    float theta = acos(clamp(d.y, -1.0, 1.0));
    float phi = atan(d.x, -d.z) - params.env.y;
    float u = phi * (0.5 * INV_PI);
    u -= floor(u);
    return vec2(u, theta * INV_PI);
}

vec3 env_uv_to_dir(vec2 uv, out float sin_theta) {
    float theta = uv.y * PI;
    float phi = uv.x * 2.0 * PI + params.env.y;
    sin_theta = sin(theta);
    return vec3(sin_theta * sin(phi), cos(theta), -sin_theta * cos(phi));
}

vec3 env_texel(uint x, uint y) {
    uint k = (y * ENV_WIDTH + x) * 2u;
    vec2 rg = unpackHalf2x16(shading_word(params.tables.z, k));
    vec2 b_ = unpackHalf2x16(shading_word(params.tables.z, k + 1u));
    return vec3(rg, b_.x) * params.env.x;
}

// Cell (x, y) holding uv.
uvec2 env_cell(vec2 uv) {
    return uvec2(min(uint(uv.x * float(ENV_WIDTH)), ENV_WIDTH - 1u), min(uint(uv.y * float(ENV_HEIGHT)), ENV_HEIGHT - 1u));
}

// Float index of row y's conditional CDF in the distribution section.
uint env_row_cdf(uint y) {
    return ENV_HEIGHT + 2u + y * (ENV_WIDTH + 1u);
}

// Solid-angle pdf of env_sample choosing direction d.
float env_pdf(vec3 d) {
    vec2 uv = env_dir_to_uv(d);
    uvec2 c = env_cell(uv);
    uint base = params.tables.w;
    float pm = shading_float(base, c.y + 1u) - shading_float(base, c.y);
    uint row = env_row_cdf(c.y);
    float pc = shading_float(base, row + c.x + 1u) - shading_float(base, row + c.x);
    float pdf_uv = pm * float(ENV_HEIGHT) * pc * float(ENV_WIDTH);
    float sin_theta = sin(uv.y * PI);
    return sin_theta > 0.0 ? pdf_uv / (2.0 * PI * PI * sin_theta) : 0.0;
}

vec3 env_radiance(vec3 d) {
    uvec2 c = env_cell(env_dir_to_uv(d));
    return env_texel(c.x, c.y);
}

// Importance-samples a direction; returns its radiance, with its solid-angle pdf.
vec3 env_sample(float u1, float u2, out vec3 d, out float pdf) {
    uint base = params.tables.w;
    uint y = cdf_search(base, 0u, ENV_HEIGHT, u1);
    float c0 = shading_float(base, y);
    float c1 = shading_float(base, y + 1u);
    float dy = c1 > c0 ? (u1 - c0) / (c1 - c0) : 0.5;
    uint row = env_row_cdf(y);
    uint x = cdf_search(base, row, ENV_WIDTH, u2);
    float r0 = shading_float(base, row + x);
    float r1 = shading_float(base, row + x + 1u);
    float dx = r1 > r0 ? (u2 - r0) / (r1 - r0) : 0.5;
    vec2 uv = vec2((float(x) + clamp(dx, 0.0, 1.0)) / float(ENV_WIDTH), (float(y) + clamp(dy, 0.0, 1.0)) / float(ENV_HEIGHT));
    float sin_theta;
    d = env_uv_to_dir(uv, sin_theta);
    float pdf_uv = (c1 - c0) * float(ENV_HEIGHT) * (r1 - r0) * float(ENV_WIDTH);
    pdf = sin_theta > 0.0 ? pdf_uv / (2.0 * PI * PI * sin_theta) : 0.0;
    return env_texel(x, y);
}

// Radiance arriving along d from outside the scene.
vec3 escaped(vec3 d) {
    if (ENV_WIDTH > 0u) return env_radiance(d);
    return params.background.rgb;
}

#endif
