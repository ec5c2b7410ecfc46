// Environment map lookup and importance sampling (the path integrator and
// shaders/sample_probe.comp): texels and the piecewise-constant distribution live in
// the shading buffer (sections in common/path.glsl). Needs ENV_WIDTH, ENV_HEIGHT.
#ifndef ARBOR_ENVMAP_GLSL
#define ARBOR_ENVMAP_GLSL

#include "common/sampling.glsl"

// The largest float below 1.
const float ONE_MINUS_EPSILON = 0.99999994;

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

// The map's direction convention (render::integrators::envdist::uv_to_dir / dir_to_uv): v = theta
// / pi from +y (row 0 at the top); u = 0.5 looks along -z, 0.75 along +x; the map
// turns by params.env_rotation radians about +y (counter-clockwise seen from above).
vec2 env_dir_to_uv(vec3 d) {
    float theta = acos(clamp(d.y, -1.0, 1.0));
    float u = (atan(-d.x, d.z) + params.env_rotation) * (0.5 * INV_PI);
    u -= floor(u);
    return vec2(u, theta * INV_PI);
}

vec3 env_uv_to_dir(vec2 uv, out float sin_theta) {
    float theta = uv.y * PI;
    float phi = uv.x * 2.0 * PI - params.env_rotation;
    sin_theta = sin(theta);
    return vec3(-sin_theta * sin(phi), cos(theta), sin_theta * cos(phi));
}

vec3 env_texel(uint x, uint y) {
    uint k = (y * ENV_WIDTH + x) * 2u;
    vec2 rg = unpackHalf2x16(shading_word(params.env_texel_table, k));
    vec2 b_ = unpackHalf2x16(shading_word(params.env_texel_table, k + 1u));
    return vec3(rg, b_.x) * params.env_intensity;
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
    uint base = params.env_distribution_table;
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

// One dimension of render::integrators::envdist's sampler: the cell of u in the n-cell CDF at
// float `first`, the continuous position in [0, 1) and the cell's density.
float env_sample_1d(uint first, uint n, float u, out uint cell, out float pdf) {
    u = clamp(u, 0.0, ONE_MINUS_EPSILON);
    uint base = params.env_distribution_table;
    cell = cdf_search(base, first, n, u);
    float c0 = shading_float(base, first + cell);
    float w = shading_float(base, first + cell + 1u) - c0;
    float du = w > 0.0 ? (u - c0) / w : 0.0;
    pdf = w * float(n);
    return min((float(cell) + du) / float(n), ONE_MINUS_EPSILON);
}

// Importance-samples a direction (u2 picks the row, u1 the column); returns its
// radiance, with its solid-angle pdf and the cell it came from.
vec3 env_sample(float u1, float u2, out vec3 d, out float pdf, out uvec2 cell) {
    uint y, x;
    float pv, pu;
    float v = env_sample_1d(0u, ENV_HEIGHT, u2, y, pv);
    float u = env_sample_1d(env_row_cdf(y), ENV_WIDTH, u1, x, pu);
    float sin_theta;
    d = env_uv_to_dir(vec2(u, v), sin_theta);
    pdf = sin_theta > 0.0 ? pu * pv / (2.0 * PI * PI * sin_theta) : 0.0;
    cell = uvec2(x, y);
    return env_texel(x, y);
}

// Radiance arriving along d from outside the scene.
vec3 escaped(vec3 d) {
    if (ENV_WIDTH > 0u) return env_radiance(d);
    return params.background;
}

#endif
