// The structure's two buffers as uniform texel buffers (RGBA32UI views), read with
// texelFetch: on llvmpipe one vector gather, where a storage-buffer load is a loop over
// the lanes with a branch per lane and word (docs/lavapipe.md). Byte layouts are those
// of each structure's `to_gpu`; these helpers only address 16-, 8- and 4-byte units.
#ifndef ARBOR_ACCEL_TEXELS_GLSL
#define ARBOR_ACCEL_TEXELS_GLSL

layout(set = 0, binding = BINDING_ACCEL_NODES) uniform usamplerBuffer accel_node_texels;
layout(set = 0, binding = BINDING_ACCEL_INDICES) uniform usamplerBuffer accel_index_texels;

// 16-byte unit k of the node buffer.
uvec4 node_texel(uint k) { return texelFetch(accel_node_texels, int(k)); }
// 8-byte unit k of the node buffer.
uvec2 node_pair(uint k) {
    uvec4 t = node_texel(k >> 1u);
    return (k & 1u) == 0u ? t.xy : t.zw;
}
// 4-byte word k of the node buffer.
uint node_word(uint k) { return node_texel(k >> 2u)[k & 3u]; }
// Primitive index k.
uint accel_index(uint k) { return texelFetch(accel_index_texels, int(k >> 2u))[k & 3u]; }

#endif
