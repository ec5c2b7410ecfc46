// Microfacet BSDFs with the Trowbridge-Reitz (GGX) distribution, isotropic, in the
// shading frame of n (docs/materials.md):
// - a rough conductor: D G2 F / (4 cos_o cos_i), Fresnel from a complex index of
//   refraction (eta, k per channel) or Schlick's form from a base colour;
// - a rough dielectric (Walter et al. 2007), reflection and refraction through the
//   same microsurface, Fresnel of the dielectric interface.
// G2 is Smith's height-correlated masking-shadowing; both sample the distribution of
// the normals visible from wo (Heitz 2018), so a sample's pdf is D_wo(h) times the
// Jacobian of the reflection or refraction about h, the pdf the evaluation reports.
// Transmission is for radiance (camera paths): the eta^2 of the BTDF cancels against
// the radiance's compression, as for smooth glass.
#ifndef ARBOR_MICROFACET_GLSL
#define ARBOR_MICROFACET_GLSL

#include "common/sampling.glsl"

// Below this alpha (0.001, roughness 0.032; src/gpu/bindings.rs) a surface is
// smooth: a delta lobe, as the mirror and glass (D would overflow a float near the
// lobe's centre).
#define ALPHA_SMOOTH uintBitsToFloat(SMOOTH_ALPHA_BITS)

// D(h) of a unit half vector whose cosine with n is c.
float ggx_d(float c, float alpha) {
    if (c <= 0.0) return 0.0;
    float a2 = alpha * alpha;
    float t = c * c * (a2 - 1.0) + 1.0;
    return a2 / (PI * t * t);
}

// Smith's Lambda of a direction whose cosine with n is c (either side).
float ggx_lambda(float c, float alpha) {
    float c2 = c * c;
    if (c2 <= 0.0) return 3.0e38;
    float tan2 = max(0.0, 1.0 - c2) / c2;
    return 0.5 * (sqrt(1.0 + alpha * alpha * tan2) - 1.0);
}

float ggx_g1(float c, float alpha) {
    return 1.0 / (1.0 + ggx_lambda(c, alpha));
}

// Height-correlated masking-shadowing of wo and wi.
float ggx_g2(float co, float ci, float alpha) {
    return 1.0 / (1.0 + ggx_lambda(co, alpha) + ggx_lambda(ci, alpha));
}

// The density of visible normals at h seen from wo (cos_o = wo.n > 0, oh = wo.h):
// G1(wo) max(0, wo.h) D(h) / cos_o.
float ggx_visible_pdf(float cos_o, float oh, float ch, float alpha) {
    if (oh <= 0.0) return 0.0;
    return ggx_g1(cos_o, alpha) * oh * ggx_d(ch, alpha) / cos_o;
}

// A half vector h from the visible normals seen from wo (Heitz 2018): the view is
// stretched to the hemisphere configuration of alpha 1, where the visible normals
// are a projected disk, a point is drawn on the visible part of that disk, lifted to
// the hemisphere and the result unstretched. wo is in the local frame (z = n, z > 0).
vec3 ggx_sample_visible(vec3 wo, float alpha, float u1, float u2) {
    vec3 v = normalize(vec3(alpha * wo.x, alpha * wo.y, wo.z));
    float len2 = v.x * v.x + v.y * v.y;
    vec3 t1 = len2 > 0.0 ? vec3(-v.y, v.x, 0.0) * inversesqrt(len2) : vec3(1.0, 0.0, 0.0);
    vec3 t2 = cross(v, t1);
    float r = sqrt(u1);
    float phi = 2.0 * PI * u2;
    float p1 = r * cos(phi);
    float p2 = r * sin(phi);
    // The disk's half hidden behind the view is folded onto the visible one.
    float s = 0.5 * (1.0 + v.z);
    p2 = mix(sqrt(max(0.0, 1.0 - p1 * p1)), p2, s);
    vec3 nh = p1 * t1 + p2 * t2 + sqrt(max(0.0, 1.0 - p1 * p1 - p2 * p2)) * v;
    return normalize(vec3(alpha * nh.x, alpha * nh.y, max(1.0e-7, nh.z)));
}

// Fresnel reflectance of a conductor of complex relative index eta + i k per channel
// for unpolarised light at cosine c (exact, not an approximation).
vec3 fresnel_conductor(float c, vec3 eta, vec3 k) {
    c = clamp(c, 0.0, 1.0);
    float c2 = c * c;
    float s2 = 1.0 - c2;
    vec3 t0 = eta * eta - k * k - vec3(s2);
    vec3 a2b2 = sqrt(max(t0 * t0 + 4.0 * eta * eta * k * k, vec3(0.0)));
    vec3 a = sqrt(max(0.5 * (a2b2 + t0), vec3(0.0)));
    vec3 t1 = a2b2 + vec3(c2);
    vec3 t2 = 2.0 * c * a;
    vec3 rs = (t1 - t2) / max(t1 + t2, vec3(1.0e-20));
    vec3 t3 = c2 * a2b2 + vec3(s2 * s2);
    vec3 t4 = t2 * s2;
    vec3 rp = rs * (t3 - t4) / max(t3 + t4, vec3(1.0e-20));
    return 0.5 * (rp + rs);
}

// Schlick's approximation from the reflectance f0 at normal incidence.
vec3 fresnel_schlick(float c, vec3 f0) {
    float m = clamp(1.0 - c, 0.0, 1.0);
    float m2 = m * m;
    return f0 + (vec3(1.0) - f0) * (m2 * m2 * m);
}

#endif
