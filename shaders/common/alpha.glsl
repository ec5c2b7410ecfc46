// Cut-outs and blended panes (glTF's alphaMode MASK and BLEND): whether a ray meets a
// triangle where it hits it. Twin of src/scene/alpha.rs (the CPU reference asks the
// same question the same way); called by every traversal's primitive test when
// SPEC_ALPHA is set. Needs the shading buffer, params and the vertices
// (common/layout.glsl), pcg_hash (common/rng.glsl) and the vertex colours
// (common/colors.glsl), whose alpha multiplies the material's.
//
// The section params.alpha_table of the shading buffer (src/render/dispatch/upload.rs,
// `alpha_rows`): a row per material, x its opacity, y the cutoff (0 for an opaque
// material, -1 for a blended pane), z (uint bits) the row of its albedo texture's alpha
// descriptor (0: the texture's alpha is 1 everywhere, or no texture); a descriptor row
// per such texture, x (uint bits) the first row of its alphas, y the width with the
// TEXTURE_WRAP_* bits, z the height; then the alphas, a byte each, four a word from
// the low byte, row-major from the top row.
#ifndef ARBOR_ALPHA_GLSL
#define ARBOR_ALPHA_GLSL

#include "common/textures.glsl"

// The number in [0, 1) a blended pane's alpha is compared with: a hash of the ray and
// the primitive, so that a seed gives one image and a pixel's samples (other rays)
// converge to the blend.
float blend_hash(Ray r, uint prim) {
    uint h = pcg_hash(prim);
    h = pcg_hash(h ^ floatBitsToUint(r.origin.x));
    h = pcg_hash(h ^ floatBitsToUint(r.origin.y));
    h = pcg_hash(h ^ floatBitsToUint(r.origin.z));
    h = pcg_hash(h ^ floatBitsToUint(r.dir.x));
    h = pcg_hash(h ^ floatBitsToUint(r.dir.y));
    h = pcg_hash(h ^ floatBitsToUint(r.dir.z));
    return float(h >> 8u) * (1.0 / 16777216.0);
}

// The alpha of the texel under uv (nearest, the texture's wraps) of the texture whose
// alpha descriptor is row `desc`.
float texture_alpha_at(uint desc, vec2 uv) {
    uvec4 d = floatBitsToUint(shading_row(desc));
    uint w = d.y & ((1u << TEXTURE_WRAP_U_SHIFT) - 1u);
    uint wrap_u = (d.y >> TEXTURE_WRAP_U_SHIFT) & 3u;
    uint wrap_v = (d.y >> TEXTURE_WRAP_V_SHIFT) & 3u;
    precise float x = wrap_coord(uv.x, wrap_u) * float(w);
    precise float y = (1.0 - wrap_coord(uv.y, wrap_v)) * float(d.z);
    uint ix = wrap_texel(int(floor(x)), int(w), wrap_u);
    uint iy = wrap_texel(int(floor(y)), int(d.z), wrap_v);
    uint i = iy * w + ix;
    uint byte = (shading_word(d.x, i >> 2u) >> (8u * (i & 3u))) & 255u;
    return float(byte) / 255.0;
}

#if HAS_TRIANGLES
// Whether ray r meets triangle `prim` (record `tri`, its material tri.w) at
// barycentrics (u, v): the alpha is the opacity times the alpha of the texel under the
// hit, times the vertex colours' alpha there. Whitted's rays always meet blended panes:
// its shading splits the ray there.
bool alpha_meets(uvec4 tri, uint prim, Ray r, float u, float v) {
    vec4 m = shading_row(params.alpha_table + tri.w);
    if (INTEGRATOR == INTEGRATOR_WHITTED && m.y < 0.0) return true;
    float alpha = m.x;
    uint desc = floatBitsToUint(m.z);
    if ((ALPHA_BITS & ALPHA_TEXTURES) != 0u && desc != 0u) {
        vec2 t0 = vec2(uintBitsToFloat(texelFetch(vertex_texels, int(2u * tri.x)).w),
                       uintBitsToFloat(texelFetch(vertex_texels, int(2u * tri.x + 1u)).w));
        vec2 t1 = vec2(uintBitsToFloat(texelFetch(vertex_texels, int(2u * tri.y)).w),
                       uintBitsToFloat(texelFetch(vertex_texels, int(2u * tri.y + 1u)).w));
        vec2 t2 = vec2(uintBitsToFloat(texelFetch(vertex_texels, int(2u * tri.z)).w),
                       uintBitsToFloat(texelFetch(vertex_texels, int(2u * tri.z + 1u)).w));
        precise float b0 = 1.0 - u - v;
        precise vec2 uv = t0 * b0 + t1 * u + t2 * v;
        alpha *= texture_alpha_at(desc, uv);
    }
    // An opaque material's row (cutoff 0) passes whatever the vertex alpha: no reads.
    if (VERTEX_COLORS && m.y != 0.0) alpha *= triangle_color(tri, u, v).a;
    // A branch, not a select: the hash runs only where a blended pane was hit.
    if ((ALPHA_BITS & ALPHA_BLEND) == 0u || m.y >= 0.0) return alpha >= m.y;
    return blend_hash(r, prim) < alpha;
}
#endif

// Whitted's weight of a blended pane's surface at hit h of material mat with texture
// coordinates uv (the opacity, times the texel's alpha and the vertex colours' alpha on
// a triangle); 1 for any other material. The ray on behind the pane takes 1 minus it.
float blend_weight(uint mat, vec2 uv, Hit h) {
    vec4 m = shading_row(params.alpha_table + mat);
    if (m.y >= 0.0) return 1.0;
    uint desc = floatBitsToUint(m.z);
    float alpha = m.x;
    bool triangle = h.prim < params.triangle_count;
    if ((ALPHA_BITS & ALPHA_TEXTURES) != 0u && triangle && desc != 0u) alpha *= texture_alpha_at(desc, uv);
#if HAS_TRIANGLES
    if (VERTEX_COLORS && triangle) alpha *= triangle_color(triangle_at(h.prim), h.u, h.v).a;
#endif
    return alpha;
}

#if HAS_SPHERES
// Whether ray r meets sphere i (primitive params.triangle_count + i): its material's
// opacity alone decides (a sphere's texture alpha is not read).
bool sphere_alpha_meets(uint i, Ray r) {
    uint mat = texelFetch(sphere_texels, int(2u * i + 1u)).x;
    vec4 m = shading_row(params.alpha_table + mat);
    if (INTEGRATOR == INTEGRATOR_WHITTED && m.y < 0.0) return true;
    if ((ALPHA_BITS & ALPHA_BLEND) == 0u || m.y >= 0.0) return m.x >= m.y;
    return blend_hash(r, params.triangle_count + i) < m.x;
}
#endif

#endif
