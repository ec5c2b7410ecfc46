// Vertex colours (glTF's COLOR_0, PLY's red/green/blue): linear RGBA at each vertex,
// interpolated across a triangle; the colour multiplies the base colour (the albedo,
// `material_hit` in common/path.glsl) and, where a material has alpha, the alpha
// (common/alpha.glsl). Twin of src/scene/colors.rs. Compiled in with
// SPEC_VERTEX_COLORS; needs params and the shading buffer (common/layout.glsl).
//
// The section params.vertex_color_table of the shading buffer
// (src/render/dispatch/upload.rs, `vertex_color_rows`): two words a vertex, in the
// vertex buffer's order, so a row holds two vertices; each channel a 16-bit unorm, red
// then green in the first word and blue then alpha in the second, each from the low
// half.
#ifndef ARBOR_COLORS_GLSL
#define ARBOR_COLORS_GLSL

#if HAS_TRIANGLES
// A 16-bit unorm channel as the CPU twin decodes it (a division, not unpackUnorm2x16,
// whose rounding the specification leaves open).
float unorm16(uint w) { return float(w & 0xffffu) / 65535.0; }

// The stored colour of vertex i.
vec4 vertex_color(uint i) {
    uvec4 row = floatBitsToUint(shading_row(params.vertex_color_table + (i >> 1u)));
    uvec2 w = (i & 1u) == 0u ? row.xy : row.zw;
    return vec4(unorm16(w.x), unorm16(w.x >> 16u), unorm16(w.y), unorm16(w.y >> 16u));
}

// The colour at barycentrics (u, v) of triangle `tri` (its vertex indices xyz), without
// fused multiply-adds, as the CPU twin computes it.
vec4 triangle_color(uvec4 tri, float u, float v) {
    precise float b0 = 1.0 - u - v;
    precise vec4 c = vertex_color(tri.x) * b0 + vertex_color(tri.y) * u + vertex_color(tri.z) * v;
    return c;
}
#endif

// The base colour's factor at hit h: its triangle's colour; white on a sphere or in a
// scene without vertex colours.
vec3 hit_tint(Hit h) {
#if HAS_TRIANGLES
    if (VERTEX_COLORS && h.prim < params.triangle_count) return triangle_color(triangle_at(h.prim), h.u, h.v).rgb;
#endif
    return vec3(1.0);
}

#endif
