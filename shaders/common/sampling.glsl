// Sampling helpers of the path integrator: orthonormal bases, hemisphere, cone and
// sphere sampling, the power heuristic. Every sampler's pdf has a twin evaluation
// here, so that light sampling and BSDF sampling weigh one another exactly (MIS).
#ifndef ARBOR_SAMPLING_GLSL
#define ARBOR_SAMPLING_GLSL

const float PI = 3.14159265358979;
const float INV_PI = 0.318309886183791;

// Tangent and bitangent of unit n (Duff et al. 2017, "Building an orthonormal basis,
// revisited").
void onb(vec3 n, out vec3 t, out vec3 b) {
    float sgn = n.z >= 0.0 ? 1.0 : -1.0;
    float a = -1.0 / (sgn + n.z);
    float c = n.x * n.y * a;
    t = vec3(1.0 + sgn * n.x * n.x * a, sgn * c, -sgn * n.x);
    b = vec3(c, sgn + n.y * n.y * a, -n.y);
}

// Direction with polar cosine `cos_t` and azimuth 2 pi u about unit axis n.
vec3 around(vec3 n, float cos_t, float u) {
    vec3 t, b;
    onb(n, t, b);
    float sin_t = sqrt(max(0.0, 1.0 - cos_t * cos_t));
    float phi = 2.0 * PI * u;
    return normalize(t * (sin_t * cos(phi)) + b * (sin_t * sin(phi)) + n * cos_t);
}

// Cosine-distributed direction about n (pdf cos / pi; Malley's method).
vec3 cosine_direction(vec3 n, float u1, float u2) {
    return around(n, sqrt(max(0.0, 1.0 - u1)), u2);
}

// Uniform direction on the unit sphere (pdf 1 / (4 pi)).
vec3 uniform_sphere(float u1, float u2) {
    float z = 1.0 - 2.0 * u1;
    float r = sqrt(max(0.0, 1.0 - z * z));
    float phi = 2.0 * PI * u2;
    return vec3(r * cos(phi), r * sin(phi), z);
}

// Power heuristic with beta = 2 (Veach 1997) for one sample of each strategy.
float power_heuristic(float pf, float pg) {
    float f = pf * pf;
    float g = pg * pg;
    return f + g > 0.0 ? f / (f + g) : 0.0;
}

float luminance(vec3 c) {
    return dot(c, vec3(0.2126, 0.7152, 0.0722));
}

#endif
