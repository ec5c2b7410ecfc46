// 4-wide BVH (bvh4): how a node's children are read, for the shared traversal of
// common/wide.glsl. Layout documented in src/accel/bvh/wide.rs: 7 texels per node, the
// four children's boxes as structure of arrays (min x, min y, min z, max x, max y,
// max z) and their references (the binary BVH's encoding: bit 31 leaf,
// first << BVH_LEAF_COUNT_BITS | count - 1; 0xffffffff none).

#include "common/bvh_leaf.glsl"

void wide_keys(uint node, Ray r, vec3 inv, float limit,
               out float k0, out float k1, out float k2, out float k3,
               out uint r0, out uint r1, out uint r2, out uint r3) {
    uint base = WIDE_NODE_PLANES * node;
    vec4 lx = uintBitsToFloat(node_texel(base));
    vec4 ly = uintBitsToFloat(node_texel(base + 1u));
    vec4 lz = uintBitsToFloat(node_texel(base + 2u));
    vec4 hx = uintBitsToFloat(node_texel(base + 3u));
    vec4 hy = uintBitsToFloat(node_texel(base + 4u));
    vec4 hz = uintBitsToFloat(node_texel(base + 5u));
    uvec4 refs = node_texel(base + 6u);
    r0 = refs.x; r1 = refs.y; r2 = refs.z; r3 = refs.w;
    k0 = wide_enter(r0, vec3(lx.x, ly.x, lz.x), vec3(hx.x, hy.x, hz.x), r, inv, limit);
    k1 = wide_enter(r1, vec3(lx.y, ly.y, lz.y), vec3(hx.y, hy.y, hz.y), r, inv, limit);
    k2 = wide_enter(r2, vec3(lx.z, ly.z, lz.z), vec3(hx.z, hy.z, hz.z), r, inv, limit);
    k3 = wide_enter(r3, vec3(lx.w, ly.w, lz.w), vec3(hx.w, hy.w, hz.w), r, inv, limit);
}

#define WIDE_WIDTH 4
#include "common/wide.glsl"
