// Materials of the path integrator: evaluation, sampling and pdf agree (the pdf a
// sampler returns is the pdf `bsdf_eval` reports for that direction), and no material
// reflects more than it receives. Needs `mat_row` (the shading buffer) and, with
// HAS_TEXTURE_CODE, `texture_albedo`.
//
// Conventions: n is the shading normal turned to the side of wo (toward the viewer);
// wi points away from the surface; `f` excludes the cosine factor.
#ifndef ARBOR_BSDF_GLSL
#define ARBOR_BSDF_GLSL

#include "common/sampling.glsl"

// Whether the scene has a material of kind k (SPEC_MATERIAL_KINDS, a bit per MAT_*).
// Code for absent kinds compiles away; on llvmpipe, where every branch runs for all
// lanes, that is time saved on every bounce.
bool kind_used(uint k) { return (MATERIAL_KINDS & (1u << k)) != 0u; }

struct Material {
    vec3 albedo;      // Lambert / Phong diffuse albedo (textured), mirror and glass tint
    uint kind;        // MAT_*
    vec3 specular;    // Phong
    float shininess;  // Phong exponent
    vec3 emission;
    float ior;        // glass
    vec3 absorption;  // glass: Beer-Lambert coefficient per unit length
    uint flags;       // MAT_FLAG_TWO_SIDED | texture index + 1 << MAT_TEXTURE_SHIFT
};

Material material_at(uint id) {
    vec4 r0 = mat_row(id, 0u);
    vec4 r1 = mat_row(id, 1u);
    vec4 r2 = mat_row(id, 2u);
    vec4 r3 = mat_row(id, 3u);
    Material m;
    m.albedo = r0.rgb;
    m.kind = floatBitsToUint(r0.w);
    m.specular = r1.rgb;
    m.shininess = r1.w;
    m.emission = r2.rgb;
    m.ior = r2.w;
    m.absorption = r3.rgb;
    m.flags = floatBitsToUint(r3.w);
    if (kind_used(MAT_PHONG) && m.kind == MAT_PHONG) {
        // Energy conservation: diffuse + specular albedo at most 1 per channel.
        float s = max(max(m.albedo.r + m.specular.r, m.albedo.g + m.specular.g), m.albedo.b + m.specular.b);
        if (s > 1.0) { m.albedo /= s; m.specular /= s; }
    }
    return m;
}

bool bsdf_is_delta(Material m) {
    return (kind_used(MAT_MIRROR) && m.kind == MAT_MIRROR) || (kind_used(MAT_GLASS) && m.kind == MAT_GLASS);
}

// Probability that a Phong sample takes the specular lobe.
float phong_specular_weight(Material m) {
    float d = luminance(m.albedo);
    float s = luminance(m.specular);
    return d + s > 0.0 ? s / (d + s) : 0.0;
}

// f(wo, wi) and the solid-angle pdf of bsdf_sample choosing wi. Zero for delta
// materials and emitters (they are never evaluated, only sampled).
vec3 bsdf_eval(Material m, vec3 n, vec3 wo, vec3 wi, out float pdf) {
    pdf = 0.0;
    float cos_i = dot(n, wi);
    if (kind_used(MAT_LAMBERT) && m.kind == MAT_LAMBERT) {
        if (cos_i <= 0.0) return vec3(0.0);
        pdf = cos_i * INV_PI;
        return m.albedo * INV_PI;
    }
    if (kind_used(MAT_PHONG) && m.kind == MAT_PHONG) {
        if (cos_i <= 0.0) return vec3(0.0);
        float ps = phong_specular_weight(m);
        vec3 r = 2.0 * dot(n, wo) * n - wo;
        float ca = max(dot(r, wi), 0.0);
        float lobe = pow(ca, m.shininess);
        pdf = (1.0 - ps) * cos_i * INV_PI + ps * (m.shininess + 1.0) * 0.5 * INV_PI * lobe;
        return m.albedo * INV_PI + m.specular * ((m.shininess + 2.0) * 0.5 * INV_PI * lobe);
    }
    return vec3(0.0);
}

// Exact Fresnel reflectance of a smooth dielectric for unpolarised light; cos_i > 0,
// eta = n_transmitted / n_incident. 1 under total internal reflection.
float fresnel_dielectric(float cos_i, float eta, out float cos_t) {
    float sin2_t = (1.0 - cos_i * cos_i) / (eta * eta);
    if (sin2_t >= 1.0) { cos_t = 0.0; return 1.0; }
    cos_t = sqrt(1.0 - sin2_t);
    float rs = (cos_i - eta * cos_t) / (cos_i + eta * cos_t);
    float rp = (eta * cos_i - cos_t) / (eta * cos_i + cos_t);
    return 0.5 * (rs * rs + rp * rp);
}

// Samples wi for wo from three uniform numbers. `front`: wo is on the geometric
// normal's side (the ray arrives from outside). Returns false when the sample carries
// nothing. `weight` = f cos / pdf (the throughput factor), `pdf` the solid-angle pdf
// (for delta lobes: the discrete probability of the lobe), `delta` whether the lobe
// is a delta. `transmit`: the ray crosses the surface.
bool bsdf_sample(Material m, vec3 n, vec3 wo, bool front, vec3 u, out vec3 wi, out vec3 weight, out float pdf,
                 out bool delta, out bool transmit) {
    delta = false;
    transmit = false;
    weight = vec3(0.0);
    pdf = 0.0;
    wi = n;
    if (kind_used(MAT_LAMBERT) && m.kind == MAT_LAMBERT) {
        wi = cosine_direction(n, u.x, u.y);
        float c = dot(n, wi);
        if (c <= 0.0) return false;
        pdf = c * INV_PI;
        weight = m.albedo;
        return true;
    }
    if (kind_used(MAT_PHONG) && m.kind == MAT_PHONG) {
        float ps = phong_specular_weight(m);
        if (u.z < ps) {
            vec3 r = 2.0 * dot(n, wo) * n - wo;
            wi = around(normalize(r), pow(u.x, 1.0 / (m.shininess + 1.0)), u.y);
        } else {
            wi = cosine_direction(n, u.x, u.y);
        }
        if (dot(n, wi) <= 0.0) return false;
        vec3 f = bsdf_eval(m, n, wo, wi, pdf);
        if (pdf <= 0.0) return false;
        weight = f * dot(n, wi) / pdf;
        return true;
    }
    if (kind_used(MAT_MIRROR) && m.kind == MAT_MIRROR) {
        wi = normalize(2.0 * dot(n, wo) * n - wo);
        delta = true;
        pdf = 1.0;
        weight = m.albedo;
        return dot(n, wi) > 0.0;
    }
    if (kind_used(MAT_GLASS) && m.kind == MAT_GLASS) {
        delta = true;
        float eta = front ? m.ior : 1.0 / m.ior;
        float cos_i = min(dot(n, wo), 1.0);
        float cos_t;
        float F = fresnel_dielectric(cos_i, eta, cos_t);
        if (u.z < F) {
            wi = normalize(2.0 * cos_i * n - wo);
            pdf = F;
            weight = vec3(1.0);
            return true;
        }
        // Snell: wi = -wo / eta + (cos_i / eta - cos_t) n.
        wi = normalize(-wo / eta + (cos_i / eta - cos_t) * n);
        pdf = 1.0 - F;
        transmit = true;
        // Radiance is compressed by eta^2 when it enters a denser medium.
        weight = m.albedo / (eta * eta);
        return true;
    }
    return false;
}

#endif
