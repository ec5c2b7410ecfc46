// 8-wide BVH (bvh8): how a node's children are read, for the shared traversal of
// common/wide.glsl. Layout documented in src/accel/bvh/wide.rs: 14 texels per node,
// the eight children's boxes as structure of arrays (min x, min y, min z, max x,
// max y, max z; two texels each, children 0..3 then 4..7) and their references (the
// binary BVH's encoding: bit 31 leaf, first << BVH_LEAF_COUNT_BITS | count - 1;
// 0xffffffff none).

#include "common/bvh_leaf.glsl"

void wide_keys(uint node, Ray r, vec3 inv, float limit,
               out float k0, out float k1, out float k2, out float k3,
               out float k4, out float k5, out float k6, out float k7,
               out uint r0, out uint r1, out uint r2, out uint r3,
               out uint r4, out uint r5, out uint r6, out uint r7) {
    uint base = WIDE_NODE_PLANES * 2u * node;
    vec4 lxa = uintBitsToFloat(node_texel(base)), lxb = uintBitsToFloat(node_texel(base + 1u));
    vec4 lya = uintBitsToFloat(node_texel(base + 2u)), lyb = uintBitsToFloat(node_texel(base + 3u));
    vec4 lza = uintBitsToFloat(node_texel(base + 4u)), lzb = uintBitsToFloat(node_texel(base + 5u));
    vec4 hxa = uintBitsToFloat(node_texel(base + 6u)), hxb = uintBitsToFloat(node_texel(base + 7u));
    vec4 hya = uintBitsToFloat(node_texel(base + 8u)), hyb = uintBitsToFloat(node_texel(base + 9u));
    vec4 hza = uintBitsToFloat(node_texel(base + 10u)), hzb = uintBitsToFloat(node_texel(base + 11u));
    uvec4 ra = node_texel(base + 12u);
    uvec4 rb = node_texel(base + 13u);
    r0 = ra.x; r1 = ra.y; r2 = ra.z; r3 = ra.w;
    r4 = rb.x; r5 = rb.y; r6 = rb.z; r7 = rb.w;
    k0 = wide_enter(r0, vec3(lxa.x, lya.x, lza.x), vec3(hxa.x, hya.x, hza.x), r, inv, limit);
    k1 = wide_enter(r1, vec3(lxa.y, lya.y, lza.y), vec3(hxa.y, hya.y, hza.y), r, inv, limit);
    k2 = wide_enter(r2, vec3(lxa.z, lya.z, lza.z), vec3(hxa.z, hya.z, hza.z), r, inv, limit);
    k3 = wide_enter(r3, vec3(lxa.w, lya.w, lza.w), vec3(hxa.w, hya.w, hza.w), r, inv, limit);
    k4 = wide_enter(r4, vec3(lxb.x, lyb.x, lzb.x), vec3(hxb.x, hyb.x, hzb.x), r, inv, limit);
    k5 = wide_enter(r5, vec3(lxb.y, lyb.y, lzb.y), vec3(hxb.y, hyb.y, hzb.y), r, inv, limit);
    k6 = wide_enter(r6, vec3(lxb.z, lyb.z, lzb.z), vec3(hxb.z, hyb.z, hzb.z), r, inv, limit);
    k7 = wide_enter(r7, vec3(lxb.w, lyb.w, lzb.w), vec3(hxb.w, hyb.w, hzb.w), r, inv, limit);
}

#define WIDE_WIDTH 8
#include "common/wide.glsl"
