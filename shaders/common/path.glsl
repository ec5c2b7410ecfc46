// The path integrator (Integrator::Path): unidirectional path tracing with
// next-event estimation. At every non-delta vertex it samples each point and
// directional light, one area light (emissive triangle or sphere, chosen in
// proportion to its power from the emitter table) and the environment map, and
// weighs area-light and environment samples against BSDF sampling with the power
// heuristic. Russian roulette from depth RR_DEPTH. Depth counts path segments: 1
// shows only what emits, 2 adds direct light (Mitsuba's convention).
//
// Only what the scene has is compiled in: EMITTER_COUNT, ENV_WIDTH and HAS_TEXTURES
// are specialization constants, so without emitters there is no light-table code,
// without a map no environment code, without textures no texture code.
//
// Shading-buffer sections after the materials and lights (row bases in
// params, `*_table`; src/render/dispatch/tables.rs writes them):
//   emitters (emitter_table): one row each: x primitive (uint bits), y CDF at its start,
//     z its probability; params.emitter_power is the total power
//   textures (texture_table): one row each: x first texel row (uint bits), y width and wrap
//     modes, z height, w mean luminance (an emission texture's, else 0); texels 4 per
//     row, each 0x00BBGGRR, row-major from the top row (common/textures.glsl)
//   environment texels (env_texel_table): 2 per row, each two words packHalf2x16(r, g),
//     packHalf2x16(b, 0), row-major from the top row (the +y pole)
//   environment distribution (env_distribution_table): floats 4 per row, the layout of
//     `render::integrators::envdist` (marginal CDF, then one conditional CDF per row)
#ifndef ARBOR_PATH_GLSL
#define ARBOR_PATH_GLSL

#include "common/sampling.glsl"

#include "common/envmap.glsl"

// --- area lights ---------------------------------------------------------------

// Emitted radiance of material m leaving a surface of geometric normal gn toward -dir.
vec3 emitted(Material m, vec3 gn, vec3 dir) {
    if ((m.flags & MAT_FLAG_TWO_SIDED) != 0u || dot(gn, dir) < 0.0) return m.emission;
    return vec3(0.0);
}

// The power by which the emitter table chose primitive `prim` of material `mat`: from
// the material's emission factor (not textured at a point).
float emitter_power(uint prim, uint mat) {
    Material m = material_at(mat);
    float area = 0.0;
#if HAS_TRIANGLES
    if (prim < params.triangle_count) {
        uvec4 tri = triangle_at(prim);
        vec3 a = vertex_position(tri.x);
        area = 0.5 * length(cross(vertex_position(tri.y) - a, vertex_position(tri.z) - a));
    }
#endif
#if HAS_SPHERES
    if (prim >= params.triangle_count) {
        float r = sphere_center_radius(prim - params.triangle_count).w;
        area = 4.0 * PI * r * r;
    }
#endif
    float sides = (m.flags & MAT_FLAG_TWO_SIDED) != 0u ? 2.0 : 1.0;
    // An emission texture scales the power by its mean luminance (the texture row's
    // w), as the host's emitter table does.
    float map = HAS_TEXTURES && m.emission_map != 0u ? shading_row(params.texture_table + m.emission_map - 1u).w : 1.0;
    return luminance(m.emission) * map * area * sides;
}

// Solid-angle pdf, from point p, of sampling a sphere by its cone (outside) or by
// area (inside), for a point at distance t along unit d with the sphere normal gn.
float sphere_light_pdf(vec3 p, vec3 c, float r, float t, vec3 d, vec3 gn) {
    vec3 pc = c - p;
    float d2 = dot(pc, pc);
    if (d2 > r * r) {
        float sin2 = r * r / d2;
        float cos_max = sqrt(max(0.0, 1.0 - sin2));
        float one_minus = sin2 / (1.0 + cos_max);
        return 1.0 / (2.0 * PI * one_minus);
    }
    float cos_l = abs(dot(gn, d));
    return cos_l > 0.0 ? t * t / (4.0 * PI * r * r * cos_l) : 0.0;
}

// Pdf with which next-event estimation from p would have chosen the point where the
// ray (p, d) hit primitive `prim` at distance t with geometric normal gn.
float light_pdf(uint prim, uint mat, vec3 p, vec3 d, float t, vec3 gn) {
    float pmf = emitter_power(prim, mat) / params.emitter_power;
#if HAS_TRIANGLES
    if (prim < params.triangle_count) {
        uvec4 tri = triangle_at(prim);
        vec3 a = vertex_position(tri.x);
        float area = 0.5 * length(cross(vertex_position(tri.y) - a, vertex_position(tri.z) - a));
        float cos_l = abs(dot(gn, d));
        return area > 0.0 && cos_l > 0.0 ? pmf * t * t / (area * cos_l) : 0.0;
    }
#endif
#if HAS_SPHERES
    vec4 s = sphere_center_radius(prim - params.triangle_count);
    return pmf * sphere_light_pdf(p, s.xyz, s.w, t, d, gn);
#else
    return 0.0;
#endif
}

// The emitter table's primitive that u chooses (by power), and its probability.
uint emitter_pick(float u, out float pmf) {
    uint base = params.emitter_table;
    uint lo = 0u;
    uint hi = EMITTER_COUNT;
    for (uint k = 0u; k < 32u && hi - lo > 1u; k++) {
        uint mid = (lo + hi) >> 1u;
        if (shading_row(base + mid).y <= u) lo = mid; else hi = mid;
    }
    vec4 row = shading_row(base + lo);
    pmf = row.z;
    return floatBitsToUint(row.x);
}

// Samples a point on an emitter seen from p: direction wi, distance, radiance and
// solid-angle pdf (the emitter's probability included). False when it sends nothing.
bool sample_emitter(vec3 p, vec3 u, out vec3 wi, out float dist, out vec3 le, out float pdf) {
    le = vec3(0.0);
    pdf = 0.0;
    wi = vec3(0.0, 1.0, 0.0);
    dist = 0.0;
    float pmf;
    uint prim = emitter_pick(u.x, pmf);
    if (pmf <= 0.0) return false;
    vec3 gn;
    uint mat;
    vec2 uv = vec2(0.0);  // where the point is, for an emission texture
#if HAS_TRIANGLES
    if (prim < params.triangle_count) {
        uvec4 tri = triangle_at(prim);
        Vertex va = vertex_at(tri.x);
        Vertex vb = vertex_at(tri.y);
        Vertex vc = vertex_at(tri.z);
        vec3 a = va.position.xyz;
        vec3 b = vb.position.xyz;
        vec3 c = vc.position.xyz;
        vec3 cr = cross(b - a, c - a);
        float area = 0.5 * length(cr);
        if (area <= 0.0) return false;
        gn = normalize(cr);
        float su = sqrt(u.y);
        vec3 q = a * (1.0 - su) + b * (su * (1.0 - u.z)) + c * (su * u.z);
        uv = vec2(va.position.w, va.normal.w) * (1.0 - su) + vec2(vb.position.w, vb.normal.w) * (su * (1.0 - u.z))
             + vec2(vc.position.w, vc.normal.w) * (su * u.z);
        vec3 to = q - p;
        float d2 = dot(to, to);
        dist = sqrt(d2);
        if (!(dist > 0.0)) return false;
        wi = to / dist;
        float cos_l = abs(dot(gn, wi));
        if (cos_l <= 0.0) return false;
        pdf = pmf * d2 / (area * cos_l);
        mat = tri.w;
    }
#endif
#if HAS_SPHERES
    if (prim >= params.triangle_count) {
        Sphere s = sphere_at(prim - params.triangle_count);
        vec3 c = s.center_radius.xyz;
        float r = s.center_radius.w;
        vec3 pc = c - p;
        float d2 = dot(pc, pc);
        mat = s.material.x;
        if (d2 > r * r) {
            float dc = sqrt(d2);
            float sin2 = r * r / d2;
            float cos_max = sqrt(max(0.0, 1.0 - sin2));
            float one_minus = sin2 / (1.0 + cos_max);
            float cos_t = 1.0 - u.y * one_minus;
            wi = around(pc / dc, cos_t, u.z);
            // Distance to the near intersection along wi.
            float b = dot(pc, wi);
            float disc = max(0.0, r * r - (d2 - b * b));
            dist = b - sqrt(disc);
            if (!(dist > 0.0)) return false;
            gn = normalize(p + wi * dist - c);
            pdf = pmf / (2.0 * PI * one_minus);
        } else {
            vec3 n = uniform_sphere(u.y, u.z);
            vec3 q = c + n * r;
            vec3 to = q - p;
            float qd2 = dot(to, to);
            dist = sqrt(qd2);
            if (!(dist > 0.0)) return false;
            wi = to / dist;
            gn = n;
            float cos_l = abs(dot(gn, wi));
            if (cos_l <= 0.0) return false;
            pdf = pmf * qd2 / (4.0 * PI * r * r * cos_l);
        }
    }
#endif
    Material m = material_at(mat);
#if HAS_SPHERES
    if (prim >= params.triangle_count) uv = sphere_uv(gn);
#endif
    if (HAS_TEXTURES && m.emission_map != 0u) m.emission *= texture_rgb(m.emission_map - 1u, uv, true);
    le = emitted(m, gn, wi);
    return pdf > 0.0 && (le.r > 0.0 || le.g > 0.0 || le.b > 0.0);
}

// The material at a hit with texture coordinates uv and vertex colour `tint`
// (`hit_tint`, common/colors.glsl): its albedo times the tint and textured, its
// emission textured and, for metallic-roughness, roughness and metallic times the
// green and blue channels of its metallic-roughness texture (the normal map bends the
// frame earlier, in `surface`).
Material material_hit(uint mat, vec2 uv, vec3 tint) {
    Material m = material_at(mat);
    if (VERTEX_COLORS) m.albedo *= tint;
    if (HAS_TEXTURES && (m.flags >> MAT_TEXTURE_SHIFT) != 0u)
        m.albedo *= texture_albedo((m.flags >> MAT_TEXTURE_SHIFT) - 1u, uv);
    if (HAS_TEXTURES && m.emission_map != 0u) m.emission *= texture_rgb(m.emission_map - 1u, uv, true);
    if (HAS_TEXTURES && is_pbr(m)) {
        uint slot = mat_bits(mat, MAT_W_MAPS) & ((1u << MAT_MAP_SHIFT) - 1u);
        if (slot != 0u) {
            vec3 t = texture_rgb(slot - 1u, uv, false);
            float rough = mat_word(mat, MAT_W_ROUGHNESS) * t.g;
            m.alpha = max(rough * rough, ALPHA_SMOOTH);
            m.metallic *= t.b;
        }
    }
    return m;
}

// --- the integrator -------------------------------------------------------------

// A path's vertex: the closest hit along r (one more of g_rays; g_nodes and g_tests
// count its traversal), its surface and textured material; with `aovs` (the pixel's
// first camera ray) the pixel's AOVs from it. Whether r hit.
bool path_vertex(Ray r, bool aovs, inout Pixel px, out Hit h, out vec3 p, out vec3 err, out vec3 gn, out vec3 sn,
                 out uint mat, out vec2 uv, out Material m) {
    h.t = r.tmax; h.prim = NO_PRIM; h.u = 0.0; h.v = 0.0;
    g_nodes = 0u; g_tests = 0u;
    g_rays += 1u;
    bool hit = trace_closest(r, h);
    uv = vec2(0.0);
    if (hit) surface(h, r, p, err, gn, sn, mat, uv);
    if (hit) m = material_hit(mat, uv, hit_tint(h));
    if (aovs) {
        px.normal_depth = hit ? vec4(sn, h.t) : vec4(0.0, 0.0, 0.0, uintBitsToFloat(0x7f800000u));
        px.prim_cost.xyz = uvec3(hit ? aov_prim(h) : NO_PRIM, g_nodes, g_tests);
        px.albedo_m2.rgb = hit ? m.albedo : vec3(0.0);
    }
    return hit;
}

// Light from point and directional lights at p toward wo (no MIS: a BSDF sample never
// hits a delta light).
vec3 delta_lights(Material m, vec3 p, vec3 err, vec3 n, vec3 gnf, vec3 wo, bool front) {
    vec3 total = vec3(0.0);
    if (LIGHT_COUNT == 0u) return total;
    for (uint l = 0u; l < LIGHT_COUNT; l++) {
        vec3 at, li;
        bool point;
        light_at(l, at, point, li);
        vec3 wi;
        float dist;
        if (point) {
            vec3 to = at - p;
            dist = length(to);
            wi = to / dist;
            li /= max(dist * dist, 1e-30);
        } else {
            wi = -at;
            dist = 3.0e38;
        }
        if (dot(gnf, wi) <= 0.0 && !bsdf_transmits(m)) continue;
        float bpdf;
        vec3 f = bsdf_eval(m, n, wo, wi, front, bpdf);
        if (f == vec3(0.0)) continue;
        Ray sr;
        sr.origin = offset_ray_origin(p, err, gnf, wi); sr.dir = wi; sr.tmin = 0.0;
        sr.tmax = point ? length(at - sr.origin) : dist;
        g_rays += 1u;
        if (trace_any_coherent(sr)) continue;
        total += f * li * abs(dot(n, wi));
    }
    return total;
}

// Whether a shadow ray from p (error err, geometric normal gnf facing wi) along wi
// reaches distance dist unblocked.
bool unoccluded(vec3 p, vec3 err, vec3 gnf, vec3 wi, float dist) {
    Ray sr;
    sr.origin = offset_ray_origin(p, err, gnf, wi); sr.dir = wi; sr.tmin = 0.0;
    sr.tmax = dist * (1.0 - 1.0 / 1024.0);
    g_rays += 1u;
    return !trace_any(sr);
}

// Light from one area light at p toward wo, chosen by power and sampled at a point by
// u (a shadow ray), weighted against BSDF sampling by the power heuristic with `mis`.
vec3 area_light(Material m, vec3 p, vec3 err, vec3 n, vec3 gnf, vec3 wo, bool front, vec3 u, bool mis) {
    vec3 wi, le;
    float dist, lpdf;
    if (!sample_emitter(p, u, wi, dist, le, lpdf) || (dot(gnf, wi) <= 0.0 && !bsdf_transmits(m))) return vec3(0.0);
    float bpdf;
    vec3 f = bsdf_eval(m, n, wo, wi, front, bpdf);
    if (f == vec3(0.0) || !unoccluded(p, err, gnf, wi, dist)) return vec3(0.0);
    float w = mis ? power_heuristic(lpdf, bpdf) : 1.0;
    return f * le * (abs(dot(n, wi)) * w / lpdf);
}

// Next-event estimation at a non-delta vertex toward wo: every point and directional
// light, one area light and the environment map, weighed against BSDF sampling as
// `mis` says (MIS_*: path's MIS_MODE; SPPM's visible points take light sampling alone,
// MIS_LIGHT), each term times beta added to L. Draws the same random numbers whatever
// `mis` is.
void direct_light(Material m, vec3 p, vec3 err, vec3 n, vec3 gnf, vec3 wo, bool front, inout uint rng, uint mis,
                  vec3 beta, inout vec3 L) {
    L += beta * delta_lights(m, p, err, n, gnf, wo, front);
    if (EMITTER_COUNT > 0u && mis != MIS_BSDF) {
        vec3 u3 = vec3(rng_next(rng), rng_next(rng), rng_next(rng));
        L += beta * area_light(m, p, err, n, gnf, wo, front, u3, mis == MIS_BOTH);
    } else if (EMITTER_COUNT > 0u) {
        rng_next(rng); rng_next(rng); rng_next(rng);
    }
    if (ENV_WIDTH > 0u && mis != MIS_BSDF) {
        vec3 wi;
        float epdf;
        uvec2 ecell;
        vec3 ele = env_sample(rng_next(rng), rng_next(rng), wi, epdf, ecell);
        if (epdf > 0.0 && (dot(gnf, wi) > 0.0 || bsdf_transmits(m))) {
            float bpdf;
            vec3 f = bsdf_eval(m, n, wo, wi, front, bpdf);
            if (f != vec3(0.0) && unoccluded(p, err, gnf, wi, 3.0e38)) {
                float w = mis == MIS_BOTH ? power_heuristic(epdf, bpdf) : 1.0;
                L += beta * f * ele * (abs(dot(n, wi)) * w / epdf);
            }
        }
    } else if (ENV_WIDTH > 0u) {
        rng_next(rng); rng_next(rng);
    }
}

// A path's next segment from a vertex at p (error err, shading normal n and geometric
// normal gnf on wo's side, `front`: wo outside): samples the BSDF, and where the sample
// carries light, makes r the new ray and sigma the absorption of the medium it enters;
// `weight` the throughput factor, `bpdf` and `sdelta` the sample's pdf and lobe. False
// when the path ends here (r and sigma untouched). Path, SPPM's camera paths and
// photons all step this way.
bool next_ray(Material m, vec3 p, vec3 err, vec3 n, vec3 gnf, vec3 wo, bool front, inout uint rng, inout Ray r,
              inout vec3 sigma, out vec3 weight, out float bpdf, out bool sdelta) {
    vec3 wi;
    bool transmit;
    vec3 u3 = vec3(rng_next(rng), rng_next(rng), rng_next(rng));
    if (!bsdf_sample(m, n, wo, front, u3, wi, weight, bpdf, sdelta, transmit)) return false;
    // A reflected ray must leave on the viewer's side of the true surface, a
    // transmitted one on the other.
    if ((dot(gnf, wi) > 0.0) == transmit) return false;
    if (transmit && (is_glass(m) || is_rough_dielectric(m))) sigma = front ? m.absorption : vec3(0.0);
    r.origin = offset_ray_origin(p, err, gnf, wi);
    r.dir = wi;
    r.tmin = 0.0;
    r.tmax = uintBitsToFloat(0x7f800000u);
    return true;
}

void path_main() {
    PixelJob job;
    Pixel out_px;
    if (!pixel_job(job, out_px)) return;
    uint slot = job.slot, pixel = job.pixel, i = job.i, j = job.j;

    g_rays = 0u;
    for (uint s = sample_begin(out_px); s < DISPATCH_SAMPLE_END; s++) {
        sample_start();
        uint rng = rng_init(pixel, s, params.seed);
        Ray r;
        r.origin = params.cam_eye;
        r.dir = camera_ray_dir(i, j, rng_next(rng), rng_next(rng));
        r.tmin = 0.0;
        r.tmax = uintBitsToFloat(0x7f800000u);
        vec3 L = vec3(0.0);
        vec3 beta = vec3(1.0);
        bool prev_delta = true;  // the camera ray counts as a delta lobe: no MIS
        float prev_pdf = 0.0;
        vec3 prev_p = r.origin;
        vec3 sigma = vec3(0.0);  // absorption of the medium the ray travels in
        for (uint depth = 0u; depth < MAX_DEPTH; depth++) {
            Hit h;
            vec3 p, err, gn, sn;
            uint mat;
            vec2 uv;
            Material m;
            bool hit = path_vertex(r, s == 0u && depth == 0u, out_px, h, p, err, gn, sn, mat, uv, m);
            if (sigma != vec3(0.0)) beta *= exp(-sigma * h.t);
            if (!hit) {
                vec3 le = escaped(r.dir);
                float w = 1.0;
                if (ENV_WIDTH > 0u && !prev_delta) {
                    if (MIS_MODE == MIS_LIGHT) w = 0.0;
                    else if (MIS_MODE == MIS_BOTH) w = power_heuristic(prev_pdf, env_pdf(r.dir));
                }
                L += beta * le * w;
                break;
            }
            vec3 le = emitted(m, gn, r.dir);
            if (le != vec3(0.0)) {
                float w = 1.0;
                if (EMITTER_COUNT > 0u && !prev_delta) {
                    if (MIS_MODE == MIS_LIGHT) w = 0.0;
                    else if (MIS_MODE == MIS_BOTH) w = power_heuristic(prev_pdf, light_pdf(h.prim, mat, prev_p, r.dir, h.t, gn));
                }
                L += beta * le * w;
            }
            if (m.kind == MAT_EMISSIVE || depth + 1u >= MAX_DEPTH) break;
            bool front = dot(gn, r.dir) < 0.0;
            vec3 gnf = front ? gn : -gn;
            vec3 n = dot(sn, r.dir) < 0.0 ? sn : -sn;
            vec3 wo = -r.dir;
            bool delta = bsdf_is_delta(m);
            if (!delta) {
                direct_light(m, p, err, n, gnf, wo, front, rng, MIS_MODE, beta, L);
            }
            vec3 weight;
            float bpdf;
            bool sdelta;
            if (!next_ray(m, p, err, n, gnf, wo, front, rng, r, sigma, weight, bpdf, sdelta)) break;
            beta *= weight;
            prev_delta = sdelta;
            prev_pdf = bpdf;
            prev_p = p;
            if (depth + 1u >= RR_DEPTH) {
                float q = min(max(max(beta.r, beta.g), beta.b), 0.95);
                if (rng_next(rng) >= q) break;
                beta /= q;
            }
        }
        if (g_suspended) break;
        // A sample that went non-finite (a degenerate configuration) counts as black.
        if (any(isnan(L)) || any(isinf(L))) L = vec3(0.0);
        out_px.radiance += vec4(L, 1.0);
        float y = luminance(L);
        out_px.albedo_m2.w += y * y;
        sample_done();
    }
    out_px.prim_cost.w += job_rays();
    if (g_overflow) out_px.prim_cost.w |= OVERFLOW_FLAG;
    job_end();
    pixels[slot] = out_px;
}

#endif
