// Stochastic progressive photon mapping (Hachisuka & Jensen 2009, as pbrt-v4 defines
// it; Integrator::Sppm, src/render/integrators/sppm.rs; docs/caustics.md). One module,
// three passes, a pipeline each (SPEC_SPPM_PASS), one iteration a dispatch
// (DISPATCH_SAMPLE_BEGIN is the iteration):
//   SPPM_PASS_CAMERA  one job a pixel of the window: a camera path through delta
//                     bounces to its first non-delta vertex, the visible point; light
//                     met on the way and next-event estimation there (light sampling
//                     alone: no BSDF-sampled light follows) go into the pixel's direct
//                     sum; the point and its radius go into `points` for the map
//   SPPM_PASS_PHOTON  one job a photon (DISPATCH_FIRST + gid of photon_count): emitted
//                     from a light chosen by power, traced through the same traversal;
//                     at each non-delta vertex after the first it is looked up in the
//                     photon map and deposited into every visible point holding it
//   SPPM_PASS_UPDATE  one job a pixel: the photons found update its radius and tau
//                     (alpha = 2/3), and the pixel's radiance sum becomes the estimate
//                     times the iterations (the frame divides by them)
// Deposits are integers (fixed point, params.photon_unit a unit, 64 bits a channel):
// integer sums do not depend on the order of the atomics, so a seed gives one image.
// Needs trace.comp's traversal, surface() and the path integrator's light sampling.
#ifndef ARBOR_SPPM_GLSL
#define ARBOR_SPPM_GLSL

layout(constant_id = SPEC_PHOTON_MAP) const uint PHOTON_MAP = SPPM_MAP_HASHGRID;
layout(constant_id = SPEC_SPPM_PASS) const uint SPPM_PASS = SPPM_PASS_CAMERA;

// What the camera and update passes write: storage.
layout(std430, set = 0, binding = BINDING_SPPM_POINTS) writeonly buffer SppmPoints { vec4 points[]; };
layout(std430, set = 0, binding = BINDING_SPPM_RECORDS) buffer SppmRecords { vec4 records[]; };
layout(std430, set = 0, binding = BINDING_SPPM_FLUX) buffer SppmFlux { uint flux[]; };
// What the photon pass reads, many times a photon: texel buffers (RGBA32UI views), on
// llvmpipe one vector gather where a storage load is a loop over the lanes. The points
// and records are the buffers above; the map holds the grid's entries or the kd-tree's
// nodes (SPEC_PHOTON_MAP).
layout(set = 0, binding = BINDING_SPPM_POINT_TEXELS) uniform usamplerBuffer point_texels;
layout(set = 0, binding = BINDING_SPPM_RECORD_TEXELS) uniform usamplerBuffer record_texels;
layout(set = 0, binding = BINDING_SPPM_GRID_HEADER) uniform usamplerBuffer header_texels;
layout(set = 0, binding = BINDING_SPPM_GRID_STARTS) uniform usamplerBuffer start_texels;
layout(set = 0, binding = BINDING_SPPM_MAP) uniform usamplerBuffer map_texels;
#define PHOTON_WORD(t, i) texelFetch(t, int((i) >> 2u))[(i) & 3u]
#define PHOTON_HEADER(i) PHOTON_WORD(header_texels, i)
#define PHOTON_START(b) PHOTON_WORD(start_texels, b)
#define PHOTON_ENTRY(k) PHOTON_WORD(map_texels, k)
#define PHOTON_POINT(v) uintBitsToFloat(texelFetch(point_texels, int(v)))
#define PHOTON_TREE_NODE(i) uintBitsToFloat(texelFetch(map_texels, int(i)))

#define PHOTON_TREE_STACK PHOTON_TREE_MAX_DEPTH
#include "common/photon_grid.glsl"
#include "common/photon_tree.glsl"

vec4 record(uint slot, uint row) { return records[slot * SPPM_RECORD_ROWS + row]; }
// The photon pass's read of a record row.
vec4 record_texel(uint slot, uint row) {
    return uintBitsToFloat(texelFetch(record_texels, int(slot * SPPM_RECORD_ROWS + row)));
}
void set_record(uint slot, uint row, vec4 v) { records[slot * SPPM_RECORD_ROWS + row] = v; }

// The render's counters (SPPM_COUNT_*), before the slots' flux words.
void sppm_count(uint counter, uint n) {
    if (n > 0u) atomicAdd(flux[counter], n);
}

// Slot v's first flux word.
uint flux_at(uint v) { return SPPM_COUNTERS + v * SPPM_FLUX_WORDS; }

// --- camera pass ------------------------------------------------------------------

void sppm_camera(PixelJob job, Pixel px) {
    uint slot = job.slot;
    uint it = DISPATCH_SAMPLE_BEGIN;
    if (it == 0u) {
        px.radiance = vec4(0.0);
        px.normal_depth = vec4(0.0, 0.0, 0.0, uintBitsToFloat(0x7f800000u));
        px.prim_cost = uvec4(NO_PRIM, 0u, 0u, 0u);
        px.albedo_m2 = vec4(0.0);
        for (uint row = 0u; row < SPPM_RECORD_ROWS; row++) set_record(slot, row, vec4(0.0));
    }
    uint rng = rng_init(job.pixel, it, params.seed);
    Ray r;
    r.origin = params.cam_eye;
    r.dir = camera_ray_dir(job.i, job.j, rng_next(rng), rng_next(rng));
    r.tmin = 0.0;
    r.tmax = uintBitsToFloat(0x7f800000u);
    vec3 L = vec3(0.0);
    vec3 beta = vec3(1.0);
    vec3 sigma = vec3(0.0);
    float travelled = 0.0;
    bool cut = false;
    bool found = false;
    vec4 point = vec4(0.0);
    g_rays = 0u;
    sample_start();
    for (uint depth = 0u; depth < MAX_DEPTH; depth++) {
        Hit h;
        vec3 p, err, gn, sn;
        uint mat;
        vec2 uv;
        Material m;
        bool hit = path_vertex(r, it == 0u && depth == 0u, px, h, p, err, gn, sn, mat, uv, m);
        if (g_suspended || g_overflow) { cut = true; break; }
        if (sigma != vec3(0.0)) beta *= exp(-sigma * h.t);
        if (!hit) {
            L += beta * escaped(r.dir);
            break;
        }
        travelled += h.t;
        L += beta * emitted(m, gn, r.dir);
        if (m.kind == MAT_EMISSIVE) break;
        bool front = dot(gn, r.dir) < 0.0;
        vec3 gnf = front ? gn : -gn;
        vec3 n = dot(sn, r.dir) < 0.0 ? sn : -sn;
        vec3 wo = -r.dir;
        if (!bsdf_is_delta(m)) {
            direct_light(m, p, err, n, gnf, wo, front, rng, MIS_LIGHT, beta, L);
            if (g_suspended || g_overflow) { cut = true; break; }
            // The radius: the pixel's own, else the user's, else a few pixel
            // footprints at the distance the camera path travelled.
            float radius = record(slot, SPPM_REC_DIRECT).w;
            if (!(radius > 0.0)) {
                float footprint = 2.0 * params.tan_half_fov * travelled / float(params.height);
                radius = params.photon_radius > 0.0 ? params.photon_radius : float(SPPM_FOOTPRINT_PIXELS) * footprint;
            }
            if (radius > 0.0 && !any(isnan(p)) && !any(isinf(p))) {
                // A Lambert point keeps its BSDF in the throughput (photon_visit).
                bool diffuse = kind_used(MAT_LAMBERT) && m.kind == MAT_LAMBERT;
                uint word = mat | (front ? SPPM_FRONT_BIT : 0u) | (diffuse ? SPPM_DIFFUSE_BIT : 0u);
                set_record(slot, SPPM_REC_POINT, vec4(p, uintBitsToFloat(word)));
                set_record(slot, SPPM_REC_NORMAL, vec4(n, uv.x));
                set_record(slot, SPPM_REC_WO, vec4(wo, uv.y));
                vec3 kept = diffuse ? beta * (m.albedo * INV_PI) : beta;
                set_record(slot, SPPM_REC_BETA, vec4(kept, float(depth + 1u)));
                // A Lambert point's colour is in its throughput already.
                if (VERTEX_COLORS && !diffuse) set_record(slot, SPPM_REC_TINT, vec4(hit_tint(h), 0.0));
                point = vec4(p, radius);
                found = true;
            }
            break;
        }
        if (depth + 1u >= MAX_DEPTH) break;
        vec3 wi, weight;
        float bpdf;
        bool sdelta, transmit;
        vec3 u3 = vec3(rng_next(rng), rng_next(rng), rng_next(rng));
        if (!bsdf_sample(m, n, wo, front, u3, wi, weight, bpdf, sdelta, transmit)) break;
        if ((dot(gnf, wi) > 0.0) == transmit) break;
        beta *= weight;
        if (transmit && (is_glass(m) || is_rough_dielectric(m))) sigma = front ? m.absorption : vec3(0.0);
        r.origin = offset_ray_origin(p, err, gnf, wi);
        r.dir = wi;
        r.tmin = 0.0;
        r.tmax = uintBitsToFloat(0x7f800000u);
    }
    if (cut || any(isnan(L)) || any(isinf(L))) L = vec3(0.0);
    if (cut) sppm_count(SPPM_COUNT_CUT, 1u);
    if (!found) set_record(slot, SPPM_REC_POINT, vec4(0.0, 0.0, 0.0, uintBitsToFloat(SPPM_NO_POINT)));
    points[slot] = found ? point : vec4(0.0);
    vec4 direct = record(slot, SPPM_REC_DIRECT);
    set_record(slot, SPPM_REC_DIRECT, vec4(direct.rgb + L, direct.w > 0.0 ? direct.w : point.w));
    px.prim_cost.w += g_rays;
    if (g_overflow) px.prim_cost.w |= OVERFLOW_FLAG;
    pixels[slot] = px;
}

// --- photon pass ------------------------------------------------------------------

// The photon being deposited: its power, the direction it arrived from, and the
// segments of its path so far.
vec3 g_photon_beta = vec3(0.0);
vec3 g_photon_wi = vec3(0.0);
uint g_photon_segments = 0u;
uint g_deposits = 0u;

// Adds `v` (in units, at least 0) to the 64-bit fixed-point word pair at `at`.
void add_fixed(uint at, float v) {
    if (!(v > 0.0)) return;
    float hi = floor(v * (1.0 / 4294967296.0));
    uint lo = uint(v - hi * 4294967296.0);
    uint before = atomicAdd(flux[at], lo);
    uint carry = before + lo < before ? 1u : 0u;
    if (hi > 0.0 || carry > 0u) atomicAdd(flux[at + 1u], uint(hi) + carry);
}

// photon_visit (common/photon_grid.glsl, common/photon_tree.glsl): the photon's flux
// times visible point v's BSDF and throughput, into v's sums, where the whole path
// (camera segments + photon segments) is within MAX_DEPTH, as path's would be.
void photon_visit(uint v, vec3 p) {
    vec4 r0 = record_texel(v, SPPM_REC_POINT);
    uint word = floatBitsToUint(r0.w);
    if (word == SPPM_NO_POINT) return;
    vec4 beta = record_texel(v, SPPM_REC_BETA);
    if (uint(beta.w) + g_photon_segments > MAX_DEPTH) return;
    vec4 n = record_texel(v, SPPM_REC_NORMAL);
    vec3 phi;
    if ((word & SPPM_DIFFUSE_BIT) != 0u) {
        // Lambert: the throughput holds albedo / pi, which bsdf_eval would give in
        // front of the surface and 0 behind it.
        if (dot(n.xyz, g_photon_wi) <= 0.0) return;
        phi = beta.rgb * g_photon_beta / params.photon_unit;
    } else {
        vec4 wo = record_texel(v, SPPM_REC_WO);
        vec3 tint = VERTEX_COLORS ? record_texel(v, SPPM_REC_TINT).rgb : vec3(1.0);
        Material m = material_hit(word & ~(SPPM_FRONT_BIT | SPPM_DIFFUSE_BIT), vec2(n.w, wo.w), tint);
        float pdf;
        vec3 f = bsdf_eval(m, n.xyz, wo.xyz, g_photon_wi, (word & SPPM_FRONT_BIT) != 0u, pdf);
        phi = beta.rgb * f * g_photon_beta / params.photon_unit;
    }
    if (any(isnan(phi)) || any(isinf(phi))) return;
    uint at = flux_at(v);
    add_fixed(at, phi.r);
    add_fixed(at + 2u, phi.g);
    add_fixed(at + 4u, phi.b);
    atomicAdd(flux[at + SPPM_FLUX_COUNT], 1u);
    g_deposits += 1u;
}

// The photon at p into the map's visible points; false when a bucket was cut short.
bool photon_deposit(vec3 p) {
    if (PHOTON_MAP == SPPM_MAP_KDTREE) {
        tree_walk(p, DISPATCH_MAP_SIZE);
        return true;
    }
    return grid_walk(p, DISPATCH_MAP_SIZE, DISPATCH_MAP_BUCKETS, SPPM_BUCKET_MOST);
}

// The scene's bounding sphere, which photons from directional lights and the
// environment enter through a disk of.
vec4 scene_sphere() {
    vec3 c = 0.5 * (params.scene_min + params.scene_max);
    return vec4(c, max(0.5 * length(params.scene_max - params.scene_min), 1e-6));
}

// --- guiding: a share of the photons toward the delta surfaces ---------------------

// The photon guide (the row after the light table): the sphere bounding the scene's
// delta surfaces, radius 0 where there are none.
vec4 photon_guide() { return shading_row(params.photon_light_table + params.photon_lights); }
const float GUIDE_SHARE = float(SPPM_GUIDE_PERCENT) / 100.0;

// The cosine of the cone from `from` around the guide (0 where `from` is inside it, or
// there is no guide: no cone).
float guide_cone(vec3 from, vec4 g) {
    vec3 to = g.xyz - from;
    float d2 = dot(to, to);
    if (!(g.w > 0.0) || d2 <= g.w * g.w * 1.0001) return 0.0;
    return sqrt(max(0.0, 1.0 - g.w * g.w / d2));
}

// The solid-angle pdf of the guide's cone (cosine cos_max, a uniform cone) at w.
float cone_pdf(vec3 from, vec3 w, vec4 g, float cos_max) {
    if (!(cos_max > 0.0) || dot(w, normalize(g.xyz - from)) < cos_max) return 0.0;
    return 1.0 / (2.0 * PI * (1.0 - cos_max));
}

// A ray entering the scene along d through the plane facing it, outside the scene's
// bounding sphere: a uniform point of the sphere's disk, or with the guide's share of
// the photons of its disk; `area_pdf` the mixture's pdf at the point (per unit area).
Ray disk_ray(vec3 d, float u1, float u2, float pick, out float area_pdf) {
    vec4 s = scene_sphere();
    vec4 g = photon_guide();
    vec3 t, b;
    onb(d, t, b);
    vec2 gc = vec2(dot(g.xyz - s.xyz, t), dot(g.xyz - s.xyz, b));
    bool guided = g.w > 0.0;
    float share = guided ? GUIDE_SHARE : 0.0;
    float phi = 2.0 * PI * u2;
    vec2 at = pick < share ? gc + g.w * sqrt(u1) * vec2(cos(phi), sin(phi)) : s.w * sqrt(u1) * vec2(cos(phi), sin(phi));
    area_pdf = (1.0 - share) / (PI * s.w * s.w) * (dot(at, at) <= s.w * s.w ? 1.0 : 0.0);
    if (guided && dot(at - gc, at - gc) <= g.w * g.w) area_pdf += share / (PI * g.w * g.w);
    Ray r;
    r.origin = s.xyz - d * (1.001 * s.w) + t * at.x + b * at.y;
    r.dir = d;
    r.tmin = 0.0;
    r.tmax = uintBitsToFloat(0x7f800000u);
    return r;
}

// A photon from the light table's light chosen by u: its ray and power (flux over the
// pdf of everything chosen). False when the light sends nothing.
bool photon_emit(inout uint rng, out Ray r, out vec3 beta) {
    beta = vec3(0.0);
    r.origin = vec3(0.0); r.dir = vec3(0.0, 1.0, 0.0); r.tmin = 0.0; r.tmax = uintBitsToFloat(0x7f800000u);
    float u = rng_next(rng);
    uint lo = 0u;
    uint hi = params.photon_lights;
    for (uint k = 0u; k < 32u && hi - lo > 1u; k++) {
        uint mid = (lo + hi) >> 1u;
        if (shading_row(params.photon_light_table + mid).x <= u) lo = mid; else hi = mid;
    }
    vec4 row = shading_row(params.photon_light_table + lo);
    float pmf = row.y;
    uint kind = floatBitsToUint(row.z);
    uint index = floatBitsToUint(row.w);
    float u1 = rng_next(rng), u2 = rng_next(rng), u3 = rng_next(rng), u4 = rng_next(rng);
    if (!(pmf > 0.0)) return false;
    if (kind == SPPM_LIGHT_DELTA) {
        if (LIGHT_COUNT == 0u) return false;
        vec3 at, li;
        bool point;
        light_at(min(index, LIGHT_COUNT - 1u), at, point, li);
        float pick = rng_next(rng);
        if (point) {
            // Uniform over the sphere, or with the guide's share in its cone.
            vec4 g = photon_guide();
            float cos_max = guide_cone(at, g);
            float share = cos_max > 0.0 ? GUIDE_SHARE : 0.0;
            r.origin = at;
            r.dir = pick < share ? around(normalize(g.xyz - at), 1.0 - u1 * (1.0 - cos_max), u2) : uniform_sphere(u1, u2);
            float pdf = (1.0 - share) / (4.0 * PI) + share * cone_pdf(at, r.dir, g, cos_max);
            beta = li / (pdf * pmf);
        } else {
            float area_pdf;
            r = disk_ray(normalize(at), u1, u2, pick, area_pdf);
            beta = li / (area_pdf * pmf);
        }
        return true;
    }
    if (kind == SPPM_LIGHT_ENV) {
        if (ENV_WIDTH == 0u) return false;
        vec3 wi;
        float epdf;
        uvec2 cell;
        vec3 le = env_sample(u1, u2, wi, epdf, cell);
        if (!(epdf > 0.0)) return false;
        float area_pdf;
        r = disk_ray(-wi, u3, u4, rng_next(rng), area_pdf);
        beta = le / (epdf * area_pdf * pmf);
        return true;
    }
    if (EMITTER_COUNT == 0u) return false;
    float ppmf;
    uint prim = emitter_pick(u1, ppmf);
    if (!(ppmf > 0.0)) return false;
    vec3 p, err, gn;
    uint mat = 0u;
    vec2 uv = vec2(0.0);
    float area = 0.0;
    p = vec3(0.0); err = vec3(0.0); gn = vec3(0.0, 1.0, 0.0);
#if HAS_TRIANGLES
    if (prim < params.triangle_count) {
        uvec4 tri = triangle_at(prim);
        Vertex va = vertex_at(tri.x);
        Vertex vb = vertex_at(tri.y);
        Vertex vc = vertex_at(tri.z);
        vec3 cr = cross(vb.position.xyz - va.position.xyz, vc.position.xyz - va.position.xyz);
        area = 0.5 * length(cr);
        if (!(area > 0.0)) return false;
        gn = normalize(cr);
        float su = sqrt(u2);
        float bu = su * (1.0 - u3), bv = su * u3;
        triangle_point(va.position.xyz, vb.position.xyz, vc.position.xyz, bu, bv, p, err);
        uv = vec2(va.position.w, va.normal.w) * (1.0 - su) + vec2(vb.position.w, vb.normal.w) * bu
             + vec2(vc.position.w, vc.normal.w) * bv;
        mat = tri.w;
    }
#endif
#if HAS_SPHERES
    if (prim >= params.triangle_count) {
        Sphere s = sphere_at(prim - params.triangle_count);
        float radius = s.center_radius.w;
        gn = uniform_sphere(u2, u3);
        p = s.center_radius.xyz + gn * radius;
        err = (abs(s.center_radius.xyz) + vec3(radius)) * (4.0 * 1.1920929e-7);
        area = 4.0 * PI * radius * radius;
        mat = s.material.x;
        uv = sphere_uv(gn);
    }
#endif
    Material m = material_at(mat);
    if (HAS_TEXTURES && m.emission_map != 0u) m.emission *= texture_rgb(m.emission_map - 1u, uv, true);
    // A two-sided emitter sends from either side, one chosen at random.
    float sides = 1.0;
    vec3 side = gn;
    if ((m.flags & MAT_FLAG_TWO_SIDED) != 0u) {
        sides = 2.0;
        if (u4 < 0.5) side = -gn;
    }
    // Cosine-distributed about the side's normal, or with the guide's share in its cone
    // (directions behind the side then carry nothing).
    vec4 g = photon_guide();
    float cos_max = guide_cone(p, g);
    float share = cos_max > 0.0 ? GUIDE_SHARE : 0.0;
    float v1 = rng_next(rng), v2 = rng_next(rng);
    vec3 d = rng_next(rng) < share ? around(normalize(g.xyz - p), 1.0 - v1 * (1.0 - cos_max), v2)
                                   : cosine_direction(side, v1, v2);
    float cos_d = dot(side, d);
    if (!(cos_d > 0.0)) return false;
    float pdf = (1.0 - share) * cos_d * INV_PI + share * cone_pdf(p, d, g, cos_max);
    vec3 le = emitted(m, side, -d);
    r.origin = offset_ray_origin(p, err, side, d);
    r.dir = d;
    beta = le * (cos_d * area * sides) / (pdf * pmf * ppmf);
    return le != vec3(0.0);
}

void sppm_photon(uint k) {
    uint it = DISPATCH_SAMPLE_BEGIN;
    // A stream of its own: not the camera's of pixel k.
    uint rng = rng_init(k, it, params.seed ^ 0x5bd1e995u);
    Ray r;
    vec3 beta;
    g_rays = 0u;
    sample_start();
    bool cut = false;
    bool truncated = false;
    if (photon_emit(rng, r, beta)) {
        vec3 sigma = vec3(0.0);
        for (uint depth = 0u; depth + 1u < MAX_DEPTH; depth++) {
            Hit h = no_hit(r);
            g_rays += 1u;
            bool hit = trace_closest(r, h);
            if (g_suspended || g_overflow) { cut = true; break; }
            if (!hit) break;
            if (sigma != vec3(0.0)) beta *= exp(-sigma * h.t);
            vec3 p, err, gn, sn;
            uint mat;
            vec2 uv;
            surface(h, r, p, err, gn, sn, mat, uv);
            Material m = material_hit(mat, uv, hit_tint(h));
            if (m.kind == MAT_EMISSIVE) break;
            bool front = dot(gn, r.dir) < 0.0;
            vec3 gnf = front ? gn : -gn;
            vec3 n = dot(sn, r.dir) < 0.0 ? sn : -sn;
            vec3 wo = -r.dir;
            // The first vertex is direct light, which the camera pass estimated.
            if (depth > 0u && !bsdf_is_delta(m)) {
                g_photon_beta = beta;
                g_photon_wi = wo;
                g_photon_segments = depth + 1u;
                if (!photon_deposit(p)) truncated = true;
            }
            vec3 weight;
            float bpdf;
            bool sdelta;
            if (!next_ray(m, p, err, n, gnf, wo, front, rng, r, sigma, weight, bpdf, sdelta)) break;
            vec3 next = beta * weight;
            // Russian roulette on the throughput's drop (pbrt's).
            float q = max(0.0, 1.0 - max(max(next.r, next.g), next.b) / max(max(max(beta.r, beta.g), beta.b), 1e-30));
            if (rng_next(rng) < q) break;
            beta = next / (1.0 - q);
        }
    }
    sppm_count(SPPM_COUNT_PHOTON_RAYS, g_rays);
    if (cut) sppm_count(SPPM_COUNT_CUT, 1u);
    if (truncated) sppm_count(SPPM_COUNT_TRUNCATED, 1u);
    sppm_count(SPPM_COUNT_DEPOSITS, g_deposits);
}

// --- update pass ------------------------------------------------------------------

// A 64-bit fixed-point word pair as a float, in units.
float fixed_value(uint at) { return float(flux[at + 1u]) * 4294967296.0 + float(flux[at]); }

void sppm_update(uint slot) {
    uint at = flux_at(slot);
    vec3 phi = vec3(fixed_value(at), fixed_value(at + 2u), fixed_value(at + 4u)) * params.photon_unit;
    float found = float(flux[at + SPPM_FLUX_COUNT]);
    for (uint w = 0u; w < SPPM_FLUX_WORDS; w++) flux[at + w] = 0u;
    vec4 direct = record(slot, SPPM_REC_DIRECT);
    vec4 tau = record(slot, SPPM_REC_TAU);
    float r = direct.w;
    if (found > 0.0 && r > 0.0) {
        float n = tau.w + (2.0 / 3.0) * found;
        float r2 = r * sqrt(n / (tau.w + found));
        float shrink = (r2 / r) * (r2 / r);
        tau = vec4((tau.rgb + phi) * shrink, n);
        r = r2;
    }
    set_record(slot, SPPM_REC_DIRECT, vec4(direct.rgb, r));
    set_record(slot, SPPM_REC_TAU, tau);
    vec3 photons = r > 0.0 ? tau.rgb / (float(params.photon_count) * PI * r * r) : vec3(0.0);
    Pixel px = pixels[slot];
    float iterations = float(DISPATCH_SAMPLE_BEGIN + 1u);
    // pbrt's estimate Ld / k + tau / (k N_p pi r^2) after k iterations, times k.
    vec3 sum = direct.rgb + photons;
    if (any(isnan(sum)) || any(isinf(sum))) sum = vec3(0.0);
    px.radiance = vec4(sum, iterations);
    pixels[slot] = px;
}

// --- the entry ------------------------------------------------------------------

void sppm_main() {
    uint local;
    if (!job_begin(local)) return;
    uint slot = local - DISPATCH_BASE;
    if (SPPM_PASS == SPPM_PASS_PHOTON) {
        sppm_photon(local);
        return;
    }
    if (SPPM_PASS == SPPM_PASS_UPDATE) {
        sppm_update(slot);
        return;
    }
    PixelJob job;
    job.slot = slot;
    uvec3 at = window_pixel(local);
    job.pixel = at.x;
    job.i = at.y;
    job.j = at.z;
    sppm_camera(job, pixels[slot]);
}

#endif
