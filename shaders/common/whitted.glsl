// The Whitted integrator (Integrator::Whitted, src/render/integrators/whitted.rs):
// the preview, whitted_main, for trace.comp. Its lights are sampled as the path
// tracer's are (delta_lights, area_light: common/path.glsl, included before it).
#ifndef ARBOR_WHITTED_GLSL
#define ARBOR_WHITTED_GLSL

// Whitted's glass splits: a refracted ray waiting while the reflected one is followed
// (at most one per split on the way from the camera, so WHITTED_SPLIT_MAX entries).
struct Branch {
    vec3 origin;
    uint depth;
    vec3 dir;
    uint splits;
    vec3 beta;
};

// The preview: camera rays; at a Lambert, Phong or rough (microfacet) surface, the
// point and directional lights (hard shadows), one area light sampled by power (as
// the path tracer does, without MIS) and the ambient term, and no further bounce;
// mirrors and smooth conductors followed (Fresnel-weighted); glass and smooth
// dielectrics split into its reflected and refracted rays, Fresnel-weighted, up to WHITTED_SPLIT
// splits a path, then only the stronger of the two. No random choice but the pixel
// jitter of samples after 0 and the area-light points.
void whitted_main() {
    PixelJob job;
    Pixel out_px;
    if (!pixel_job(job, out_px)) return;
    uint slot = job.slot, pixel = job.pixel, i = job.i, j = job.j;

    g_rays = 0u;
    for (uint s = sample_begin(out_px); s < DISPATCH_SAMPLE_END; s++) {
        sample_start();
        uint rng = rng_init(pixel, s, params.seed);
        // Sample 0 goes through the pixel centre (and feeds the AOVs); others jitter.
        float fx = 0.5, fy = 0.5;
        if (s > 0u) { fx = rng_next(rng); fy = rng_next(rng); }
        Ray r;
        r.origin = params.cam_eye;
        r.dir = camera_ray_dir(i, j, fx, fy);
        r.tmin = 0.0;
        r.tmax = uintBitsToFloat(0x7f800000u);
        vec3 L = vec3(0.0);
        vec3 beta = vec3(1.0);
        uint depth = 0u;
        uint splits = 0u;
        Branch waiting[WHITTED_SPLIT_MAX];
        uint n_waiting = 0u;
        // One ray a pass: at depth d at most 2^min(d, WHITTED_SPLIT) of them.
        for (uint pass = 0u; pass < (MAX_DEPTH << WHITTED_SPLIT); pass++) {
            Hit h;
            h.t = r.tmax; h.prim = NO_PRIM; h.u = 0.0; h.v = 0.0;
            g_nodes = 0u; g_tests = 0u;
            g_rays += 1u;
            bool hit = trace_closest(r, h);
            if (g_suspended) break;
            vec3 p, err, gn, sn;
            uint mat;
            vec2 uv;
            Material m;
            if (hit) {
                surface(h, r, p, err, gn, sn, mat, uv);
                m = material_hit(mat, uv, hit_tint(h));
            }
            if (s == 0u && pass == 0u) {
                out_px.normal_depth = hit ? vec4(sn, h.t) : vec4(0.0, 0.0, 0.0, uintBitsToFloat(0x7f800000u));
                out_px.prim_cost.xyz = uvec3(hit ? aov_prim(h) : NO_PRIM, g_nodes, g_tests);
                out_px.albedo_m2.rgb = hit ? m.albedo : vec3(0.0);
            }
            // A blended pane: its surface weighs alpha, the ray on behind it 1 - alpha
            // (split as glass is; docs/materials.md, "Alpha").
            vec3 beta_behind = vec3(0.0);
            vec3 through = r.dir;
            if (hit && (ALPHA_BITS & ALPHA_BLEND) != 0u) {
                float a = blend_weight(mat, uv, h);
                beta_behind = beta * (1.0 - a);
                beta *= a;
            }
            bool follow = false;
            if (!hit) {
                L += beta * params.background;
            } else {
                L += beta * emitted(m, gn, r.dir);
                bool front = dot(gn, r.dir) < 0.0;
                vec3 gnf = front ? gn : -gn;
                vec3 n = dot(sn, r.dir) < 0.0 ? sn : -sn;
                vec3 wo = -r.dir;
                bool more = depth + 1u < MAX_DEPTH;
                if (m.kind == MAT_LAMBERT || m.kind == MAT_PHONG || is_rough_conductor(m)
                    || is_rough_dielectric(m) || is_pbr(m)) {
                    L += beta * (bsdf_colour(m) * params.ambient * params.background
                                 + delta_lights(m, p, err, n, gnf, wo, front));
                    if (EMITTER_COUNT > 0u) {
                        vec3 u3 = vec3(rng_next(rng), rng_next(rng), rng_next(rng));
                        L += beta * area_light(m, p, err, n, gnf, wo, front, u3, false);
                    }
                } else if (((kind_used(MAT_MIRROR) && m.kind == MAT_MIRROR) || is_smooth_conductor(m)) && more) {
                    beta *= m.kind == MAT_MIRROR ? m.albedo : conductor_fresnel(m, min(dot(n, wo), 1.0));
                    r.dir = normalize(reflect(r.dir, n));
                    r.origin = offset_ray_origin(p, err, gnf, r.dir);
                    follow = true;
                } else if (is_glass(m) && more) {
                    float eta = front ? 1.0 / m.ior : m.ior;  // incident over transmitted, for refract
                    float cos_t;
                    float fresnel = fresnel_dielectric(clamp(dot(-r.dir, n), 0.0, 1.0), 1.0 / eta, cos_t);
                    vec3 reflected = normalize(reflect(r.dir, n));
                    vec3 w_reflect = vec3(fresnel);
                    vec3 w_refract = (1.0 - fresnel) * m.albedo;
                    bool take_reflect = true;
                    if (fresnel < 1.0) {
                        vec3 refracted = normalize(refract(r.dir, n, eta));
                        if (splits < WHITTED_SPLIT && n_waiting < WHITTED_SPLIT_MAX) {
                            Branch b;
                            b.origin = offset_ray_origin(p, err, gnf, refracted);
                            b.dir = refracted;
                            b.depth = depth + 1u;
                            b.splits = splits + 1u;
                            b.beta = beta * w_refract;
                            waiting[n_waiting] = b;
                            n_waiting += 1u;
                            splits += 1u;
                        } else if (luminance(w_refract) > luminance(w_reflect)) {
                            take_reflect = false;
                            beta *= w_refract;
                            r.dir = refracted;
                        }
                    }
                    if (take_reflect) {
                        beta *= w_reflect;
                        r.dir = reflected;
                    }
                    r.origin = offset_ray_origin(p, err, gnf, r.dir);
                    follow = true;
                }
            }
            if ((ALPHA_BITS & ALPHA_BLEND) != 0u && (beta_behind.r > 0.0 || beta_behind.g > 0.0 || beta_behind.b > 0.0)
                && depth + 1u < MAX_DEPTH) {
                vec3 o = offset_ray_origin(p, err, gn, through);
                if (!follow) {
                    // Nothing else follows from this hit: go on behind the pane.
                    r.origin = o;
                    r.dir = through;
                    beta = beta_behind;
                    follow = true;
                } else if (splits < WHITTED_SPLIT && n_waiting < WHITTED_SPLIT_MAX) {
                    Branch b;
                    b.origin = o;
                    b.dir = through;
                    b.depth = depth + 1u;
                    b.splits = splits + 1u;
                    b.beta = beta_behind;
                    waiting[n_waiting] = b;
                    n_waiting += 1u;
                    splits += 1u;
                }
            }
            if (follow) {
                depth += 1u;
            } else if (WHITTED_SPLIT > 0u && n_waiting > 0u) {
                n_waiting -= 1u;
                Branch b = waiting[n_waiting];
                r.origin = b.origin;
                r.dir = b.dir;
                depth = b.depth;
                splits = b.splits;
                beta = b.beta;
            } else {
                break;
            }
            r.tmin = 0.0;
            r.tmax = uintBitsToFloat(0x7f800000u);
        }
        if (g_suspended) break;
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
