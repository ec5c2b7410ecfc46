// Materials of the path integrator: evaluation, sampling and pdf agree (the pdf a
// sampler returns is the pdf `bsdf_eval` reports for that direction), and no material
// reflects more than it receives. Reads the material records (common/layout.glsl).
//
// Conventions: n is the shading normal turned to the side of wo (toward the viewer);
// wi points away from the surface; `f` excludes the cosine factor.
#ifndef ARBOR_BSDF_GLSL
#define ARBOR_BSDF_GLSL

#include "common/sampling.glsl"
#include "common/microfacet.glsl"

// Whether the scene has a material of kind k (SPEC_MATERIAL_KINDS, a bit per MAT_*).
// Code for absent kinds compiles away; on llvmpipe, where every branch runs for all
// lanes, that is time saved on every bounce.
bool kind_used(uint k) { return (MATERIAL_KINDS & (1u << k)) != 0u; }

struct Material {
    vec3 albedo;      // Lambert / Phong diffuse albedo (textured), mirror, glass and
                      // dielectric tint, conductor tint (or F0 with MAT_FLAG_SCHLICK)
    uint kind;        // MAT_*
    vec3 specular;    // Phong (0 for other kinds)
    float shininess;  // Phong exponent
    vec3 emission;
    uint emission_map; // emission texture index + 1 (0: none)
    float ior;        // glass, dielectric
    vec3 absorption;  // glass, dielectric: Beer-Lambert coefficient per unit length
    uint flags;       // MAT_FLAG_TWO_SIDED | MAT_FLAG_SCHLICK | texture index + 1 << MAT_TEXTURE_SHIFT
    float alpha;      // conductor, dielectric: GGX alpha (0: smooth)
    vec3 eta;         // conductor: complex index of refraction, real part
    vec3 k;           // conductor: imaginary part
    float metallic;   // metallic-roughness (MAT_PBR): how metallic, in [0, 1]
    float spec_weight; // MAT_PBR: the dielectric layer's weight
    vec3 f0;          // MAT_PBR: the dielectric layer's reflectance at normal incidence
};

// The decoders, one per kind (the encoders are in src/render/dispatch/upload.rs; the
// words in src/gpu/bindings.rs, MAT_W_*). The plain kinds: Lambert, Phong, mirror,
// glass, emissive.
void decode_plain(vec4 rec[MATERIAL_ROWS], inout Material m) {
    m.specular = REC_RGB(rec, MAT_W_SPECULAR_RGB);
    m.shininess = REC_WORD(rec, MAT_W_SHININESS);
    m.ior = REC_WORD(rec, MAT_W_IOR);
    m.absorption = REC_RGB(rec, MAT_W_ABSORPTION_RGB);
    if (kind_used(MAT_PHONG) && m.kind == MAT_PHONG) {
        // Energy conservation: diffuse + specular albedo at most 1 per channel.
        float s = max(max(m.albedo.r + m.specular.r, m.albedo.g + m.specular.g), m.albedo.b + m.specular.b);
        if (s > 1.0) { m.albedo /= s; m.specular /= s; }
    }
}

void decode_conductor(vec4 rec[MATERIAL_ROWS], inout Material m) {
    m.ior = REC_WORD(rec, MAT_W_IOR);
    m.alpha = REC_WORD(rec, MAT_W_ALPHA);
    m.eta = REC_RGB(rec, MAT_W_ETA_RGB);
    m.k = REC_RGB(rec, MAT_W_K_RGB);
}

void decode_dielectric(vec4 rec[MATERIAL_ROWS], inout Material m) {
    m.ior = REC_WORD(rec, MAT_W_IOR);
    m.absorption = REC_RGB(rec, MAT_W_ABSORPTION_RGB);
    m.alpha = REC_WORD(rec, MAT_W_ALPHA);
}

// Metallic-roughness (its maps are read at the hit, `material_hit` in path.glsl).
void decode_pbr(vec4 rec[MATERIAL_ROWS], inout Material m) {
    float roughness = REC_WORD(rec, MAT_W_ROUGHNESS);
    // Never a delta lobe: roughness 0 is the sharpest GGX lobe a float holds.
    m.alpha = max(roughness * roughness, ALPHA_SMOOTH);
    m.metallic = REC_WORD(rec, MAT_W_METALLIC);
    m.spec_weight = REC_WORD(rec, MAT_W_SPEC_WEIGHT);
    m.f0 = REC_RGB(rec, MAT_W_F0_RGB);
    m.ior = 1.5;
}

Material material_at(uint id) {
    vec4 rec[MATERIAL_ROWS];
    rec[0] = mat_row(id, 0u);
    rec[1] = mat_row(id, 1u);
    rec[2] = mat_row(id, 2u);
    rec[3] = mat_row(id, 3u);
    Material m;
    uint kind_word = REC_BITS(rec, MAT_W_KIND);
    m.albedo = REC_RGB(rec, MAT_W_COLOR_RGB);
    m.kind = kind_word & ((1u << MAT_MAP_SHIFT) - 1u);
    m.emission_map = kind_word >> MAT_MAP_SHIFT;
    m.emission = REC_RGB(rec, MAT_W_EMISSION_RGB);
    m.flags = REC_BITS(rec, MAT_W_FLAGS);
    m.specular = vec3(0.0);
    m.shininess = 0.0;
    m.ior = 1.0;
    m.absorption = vec3(0.0);
    m.alpha = 0.0;
    m.eta = vec3(1.0);
    m.k = vec3(0.0);
    m.metallic = 0.0;
    m.spec_weight = 0.0;
    m.f0 = vec3(0.0);
    if (kind_used(MAT_CONDUCTOR) && m.kind == MAT_CONDUCTOR) decode_conductor(rec, m);
    else if (kind_used(MAT_DIELECTRIC) && m.kind == MAT_DIELECTRIC) decode_dielectric(rec, m);
    else if (kind_used(MAT_PBR) && m.kind == MAT_PBR) decode_pbr(rec, m);
    else decode_plain(rec, m);
    return m;
}

// A smooth dielectric scatters exactly as glass; a smooth conductor as a mirror of
// Fresnel reflectance.
bool is_glass(Material m) {
    return (kind_used(MAT_GLASS) && m.kind == MAT_GLASS)
        || (kind_used(MAT_DIELECTRIC) && m.kind == MAT_DIELECTRIC && m.alpha < ALPHA_SMOOTH);
}
bool is_smooth_conductor(Material m) {
    return kind_used(MAT_CONDUCTOR) && m.kind == MAT_CONDUCTOR && m.alpha < ALPHA_SMOOTH;
}
bool is_rough_conductor(Material m) {
    return kind_used(MAT_CONDUCTOR) && m.kind == MAT_CONDUCTOR && m.alpha >= ALPHA_SMOOTH;
}
bool is_rough_dielectric(Material m) {
    return kind_used(MAT_DIELECTRIC) && m.kind == MAT_DIELECTRIC && m.alpha >= ALPHA_SMOOTH;
}

bool is_pbr(Material m) {
    return kind_used(MAT_PBR) && m.kind == MAT_PBR;
}

bool bsdf_is_delta(Material m) {
    return (kind_used(MAT_MIRROR) && m.kind == MAT_MIRROR) || is_glass(m) || is_smooth_conductor(m);
}

// Whether light may arrive through the surface, from below (next-event estimation
// then samples lights on both sides).
bool bsdf_transmits(Material m) {
    return is_rough_dielectric(m);
}

// A conductor's Fresnel reflectance at cosine c (about the half vector), tinted.
vec3 conductor_fresnel(Material m, float c) {
    if ((m.flags & MAT_FLAG_SCHLICK) != 0u) return fresnel_schlick(c, m.albedo);
    return m.albedo * fresnel_conductor(c, m.eta, m.k);
}

// The reflectance that stands for a surface where only a colour will do (the
// Whitted preview's ambient term): the albedo, a conductor's at normal incidence.
vec3 bsdf_colour(Material m) {
    if (kind_used(MAT_CONDUCTOR) && m.kind == MAT_CONDUCTOR) return conductor_fresnel(m, 1.0);
    return m.albedo;
}

// Probability that a Phong sample takes the specular lobe.
float phong_specular_weight(Material m) {
    float d = luminance(m.albedo);
    float s = luminance(m.specular);
    return d + s > 0.0 ? s / (d + s) : 0.0;
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

// Probability that a metallic-roughness sample takes the specular (GGX) lobe rather
// than the cosine one: the specular share of the reflectance at normal incidence, from
// a quarter to nine tenths while the diffuse base reflects anything.
float pbr_specular_weight(Material m) {
    float s = luminance(mix(m.spec_weight * m.f0, m.albedo, m.metallic));
    float d = (1.0 - m.metallic) * luminance(m.albedo) * (1.0 - m.spec_weight * max(max(m.f0.r, m.f0.g), m.f0.b));
    if (d <= 0.0) return 1.0;
    return clamp(s / (s + d), 0.25, 0.9);
}

// glTF 2.0's metallic-roughness BRDF (the specification's appendix B, with
// KHR_materials_specular's weight and colour): the dielectric (1 - metallic) is a
// GGX layer of Schlick reflectance Fr from f0 over a Lambert base that gets what the
// layer's strongest channel does not reflect; the metal (metallic) the same GGX lobe
// with Schlick's Fresnel from the base colour. The pdf mixes VNDF and cosine sampling.
vec3 pbr_eval(Material m, vec3 n, vec3 wo, vec3 wi, float cos_i, out float pdf) {
    pdf = 0.0;
    float co = dot(n, wo);
    if (cos_i <= 0.0 || co <= 0.0) return vec3(0.0);
    vec3 h = normalize(wo + wi);
    float oh = clamp(dot(wo, h), 0.0, 1.0);
    vec3 fr = fresnel_schlick(oh, m.f0);
    vec3 fm = fresnel_schlick(oh, m.albedo);
    float d = ggx_d(dot(n, h), m.alpha);
    float lobe = d * ggx_g2(co, cos_i, m.alpha) / (4.0 * co * cos_i);
    float ps = pbr_specular_weight(m);
    pdf = (1.0 - ps) * cos_i * INV_PI + ps * ggx_g1(co, m.alpha) * d / (4.0 * co);
    float base = (1.0 - m.metallic) * (1.0 - m.spec_weight * max(max(fr.r, fr.g), fr.b));
    return base * m.albedo * INV_PI + ((1.0 - m.metallic) * m.spec_weight * fr + m.metallic * fm) * lobe;
}

// The rough conductor's f at wi and the pdf of sampling wi (cos_i = n.wi).
vec3 conductor_eval(Material m, vec3 n, vec3 wo, vec3 wi, float cos_i, out float pdf) {
    pdf = 0.0;
    float co = dot(n, wo);
    if (cos_i <= 0.0 || co <= 0.0) return vec3(0.0);
    vec3 h = normalize(wo + wi);
    float d = ggx_d(dot(n, h), m.alpha);
    pdf = ggx_g1(co, m.alpha) * d / (4.0 * co);
    return conductor_fresnel(m, dot(wo, h)) * (d * ggx_g2(co, cos_i, m.alpha) / (4.0 * co * cos_i));
}

// The rough dielectric's f at wi and the pdf of sampling wi: reflection with the
// Fresnel probability, refraction with the rest. `front`: wo is outside.
vec3 dielectric_eval(Material m, vec3 n, vec3 wo, vec3 wi, float cos_i, bool front, out float pdf) {
    pdf = 0.0;
    float co = dot(n, wo);
    if (co <= 0.0 || cos_i == 0.0) return vec3(0.0);
    float eta = front ? m.ior : 1.0 / m.ior;
    float ct;
    if (cos_i > 0.0) {
        vec3 h = normalize(wo + wi);
        float F = fresnel_dielectric(dot(wo, h), eta, ct);
        float d = ggx_d(dot(n, h), m.alpha);
        pdf = F * ggx_g1(co, m.alpha) * d / (4.0 * co);
        return vec3(F * d * ggx_g2(co, cos_i, m.alpha) / (4.0 * co * cos_i));
    }
    // Refraction: the half vector of wo and wi through indices 1 and eta, on n's side.
    vec3 h = -(wo + eta * wi);
    float len = length(h);
    if (!(len > 0.0)) return vec3(0.0);
    h /= len;
    if (dot(n, h) < 0.0) h = -h;
    float oh = dot(wo, h);
    float ih = dot(wi, h);
    if (oh <= 0.0 || ih >= 0.0) return vec3(0.0);
    float T = 1.0 - fresnel_dielectric(oh, eta, ct);
    float denom = oh + eta * ih;
    denom *= denom;
    if (T <= 0.0 || !(denom > 1.0e-20)) return vec3(0.0);
    float d = ggx_d(dot(n, h), m.alpha);
    pdf = T * ggx_visible_pdf(co, oh, dot(n, h), m.alpha) * eta * eta * (-ih) / denom;
    return m.albedo * (T * d * ggx_g2(co, cos_i, m.alpha) * oh * (-ih) / (co * (-cos_i) * denom));
}

// f(wo, wi) and the solid-angle pdf of bsdf_sample choosing wi. Zero for delta
// materials and emitters (they are never evaluated, only sampled). `front`: wo is on
// the geometric normal's side (outside), which a dielectric's eta depends on.
vec3 bsdf_eval(Material m, vec3 n, vec3 wo, vec3 wi, bool front, out float pdf) {
    pdf = 0.0;
    float cos_i = dot(n, wi);
    if (is_rough_conductor(m)) return conductor_eval(m, n, wo, wi, cos_i, pdf);
    if (is_rough_dielectric(m)) return dielectric_eval(m, n, wo, wi, cos_i, front, pdf);
    if (is_pbr(m)) return pbr_eval(m, n, wo, wi, cos_i, pdf);
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

// A half vector from the visible normals of m's GGX surface seen from wo (u1, u2),
// in world space; false when wo grazes or lies below.
bool sample_half_vector(Material m, vec3 n, vec3 wo, float u1, float u2, out vec3 h) {
    vec3 t, b;
    onb(n, t, b);
    vec3 lo = vec3(dot(wo, t), dot(wo, b), dot(wo, n));
    h = n;
    if (lo.z <= 0.0) return false;
    vec3 lh = ggx_sample_visible(lo, m.alpha, u1, u2);
    h = normalize(t * lh.x + b * lh.y + n * lh.z);
    return dot(wo, h) > 0.0;
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
    if ((kind_used(MAT_MIRROR) && m.kind == MAT_MIRROR) || is_smooth_conductor(m)) {
        wi = normalize(2.0 * dot(n, wo) * n - wo);
        delta = true;
        pdf = 1.0;
        weight = m.kind == MAT_MIRROR ? m.albedo : conductor_fresnel(m, min(dot(n, wo), 1.0));
        return dot(n, wi) > 0.0;
    }
    if (is_glass(m)) {
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
    // The lobes that are not deltas draw wi, then one evaluation gives f and the pdf
    // (one inlined copy of bsdf_eval instead of one per kind: a smaller kernel).
    if (is_rough_conductor(m) || is_rough_dielectric(m)) {
        vec3 h;
        if (!sample_half_vector(m, n, wo, u.x, u.y, h)) return false;
        float oh = dot(wo, h);
        float ct;
        float F = is_rough_conductor(m) ? 1.0 : fresnel_dielectric(oh, front ? m.ior : 1.0 / m.ior, ct);
        if (u.z < F) {
            wi = normalize(2.0 * oh * h - wo);
        } else {
            float eta = front ? m.ior : 1.0 / m.ior;
            wi = normalize(-wo / eta + (oh / eta - ct) * h);
            transmit = true;
        }
    } else if (is_pbr(m)) {
        vec3 h;
        if (u.z >= pbr_specular_weight(m)) {
            wi = cosine_direction(n, u.x, u.y);
        } else if (sample_half_vector(m, n, wo, u.x, u.y, h)) {
            wi = normalize(2.0 * dot(wo, h) * h - wo);
        } else {
            return false;
        }
    } else if (kind_used(MAT_PHONG) && m.kind == MAT_PHONG) {
        if (u.z < phong_specular_weight(m)) {
            vec3 r = 2.0 * dot(n, wo) * n - wo;
            wi = around(normalize(r), pow(u.x, 1.0 / (m.shininess + 1.0)), u.y);
        } else {
            wi = cosine_direction(n, u.x, u.y);
        }
    } else {
        return false;
    }
    float c = dot(n, wi);
    if (transmit ? c >= 0.0 : c <= 0.0) return false;
    vec3 f = bsdf_eval(m, n, wo, wi, front, pdf);
    if (!(pdf > 0.0)) return false;
    weight = f * abs(c) / pdf;
    return true;
}

#endif
