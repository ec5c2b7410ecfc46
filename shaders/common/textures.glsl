// Texture lookup (section params.texture_table of the shading buffer, common/path.glsl): one row
// per texture, x first texel row (uint bits), y width (TEXTURE_WRAP_* bits above it),
// z height, w the mean luminance an emission texture scales its light's power by;
// texels 4 per row, each 0x00BBGGRR, row-major from the top row. Colour textures are
// sRGB-encoded and decoded before filtering; data textures (metallic-roughness, normal
// maps) are linear. Needs the shading buffer and params (common/layout.glsl).
#ifndef ARBOR_TEXTURES_GLSL
#define ARBOR_TEXTURES_GLSL

float srgb_to_linear(float c) {
    return c <= 0.04045 ? c / 12.92 : pow((c + 0.055) / 1.055, 2.4);
}

vec3 texel(uint base, uint w, uint x, uint y, bool srgb) {
    uint word = shading_word(base, y * w + x);
    vec3 c = vec3(float(word & 255u), float((word >> 8u) & 255u), float((word >> 16u) & 255u)) / 255.0;
    if (!srgb) return c;
    return vec3(srgb_to_linear(c.r), srgb_to_linear(c.g), srgb_to_linear(c.b));
}

// A texture coordinate reduced to one period of its wrap mode (the table row's
// TEXTURE_WRAP_* bits: 0 repeat, 1 clamp to edge, 2 mirrored repeat): [0, 1), [-1, 2]
// or [0, 2), so that texel indices stay small.
float wrap_coord(float u, uint mode) {
    if (mode == 1u) return clamp(u, -1.0, 2.0);
    if (mode == 2u) return u - 2.0 * floor(0.5 * u);
    return u - floor(u);
}

// Texel index i of a row or column of n texels, wrapped by mode.
uint wrap_texel(int i, int n, uint mode) {
    if (mode == 1u) return uint(clamp(i, 0, n - 1));
    if (mode == 2u) {
        int p = (i % (2 * n) + 2 * n) % (2 * n);
        return uint(p < n ? p : 2 * n - 1 - p);
    }
    return uint((i % n + n) % n);
}

// Bilinear, with the texture's wrap along u and v; `srgb`: decode to linear before
// filtering.
vec3 texture_rgb(uint tex, vec2 uv, bool srgb) {
    vec4 row = shading_row(params.texture_table + tex);
    uint base = floatBitsToUint(row.x);
    uint wbits = floatBitsToUint(row.y);
    uint w = wbits & ((1u << TEXTURE_WRAP_U_SHIFT) - 1u);
    uint wrap_u = (wbits >> TEXTURE_WRAP_U_SHIFT) & 3u;
    uint wrap_v = (wbits >> TEXTURE_WRAP_V_SHIFT) & 3u;
    uint h = floatBitsToUint(row.z);
    float x = wrap_coord(uv.x, wrap_u) * float(w) - 0.5;
    // Row 0 is the top, v = 1.
    float y = (1.0 - wrap_coord(uv.y, wrap_v)) * float(h) - 0.5;
    float fx = floor(x);
    float fy = floor(y);
    float ax = x - fx;
    float ay = y - fy;
    int ix = int(fx);
    int iy = int(fy);
    uint x0 = wrap_texel(ix, int(w), wrap_u);
    uint x1 = wrap_texel(ix + 1, int(w), wrap_u);
    uint y0 = wrap_texel(iy, int(h), wrap_v);
    uint y1 = wrap_texel(iy + 1, int(h), wrap_v);
    vec3 a = mix(texel(base, w, x0, y0, srgb), texel(base, w, x1, y0, srgb), ax);
    vec3 b = mix(texel(base, w, x0, y1, srgb), texel(base, w, x1, y1, srgb), ax);
    return mix(a, b, ay);
}

vec3 texture_albedo(uint tex, vec2 uv) { return texture_rgb(tex, uv, true); }

// The shading normal n bent by material mat's normal map (MAT_PBR with a normal
// texture) at uv, for a triangle of corners p0..p2 with texture coordinates t0..t2:
// the map's x runs along the direction in which u grows, y along v, z along n, each
// in [-1, 1] from the texel; x and y scaled by the material's normal scale. The
// tangent frame is the triangle's (no vertex tangents), made orthogonal to n; n
// itself where the triangle's texture coordinates are degenerate.
vec3 normal_mapped(uint mat, vec3 n, vec2 uv, vec3 p0, vec3 p1, vec3 p2, vec2 t0, vec2 t1, vec2 t2) {
    if ((mat_bits(mat, MAT_W_KIND) & ((1u << MAT_MAP_SHIFT) - 1u)) != MAT_PBR) return n;
    uint slot = mat_bits(mat, MAT_W_MAPS) >> MAT_MAP_SHIFT;
    if (slot == 0u) return n;
    vec3 e1 = p1 - p0;
    vec3 e2 = p2 - p0;
    vec2 d1 = t1 - t0;
    vec2 d2 = t2 - t0;
    float det = d1.x * d2.y - d2.x * d1.y;
    if (!(abs(det) > 1e-20)) return n;
    vec3 dpdu = (e1 * d2.y - e2 * d1.y) / det;
    vec3 dpdv = (e2 * d1.x - e1 * d2.x) / det;
    vec3 t = dpdu - n * dot(n, dpdu);
    if (!(dot(t, t) > 1e-30)) return n;
    t = normalize(t);
    vec3 b = cross(n, t);
    if (dot(b, dpdv) < 0.0) b = -b;
    vec3 c = texture_rgb(slot - 1u, uv, false) * 2.0 - 1.0;
    float scale = mat_word(mat, MAT_W_NORMAL_SCALE);
    vec3 bent = t * (c.x * scale) + b * (c.y * scale) + n * c.z;
    return dot(bent, bent) > 0.0 ? normalize(bent) : n;
}

#endif
