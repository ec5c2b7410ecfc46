// The structure's two buffers as uniform texel buffers (RGBA32UI views), read with
// texelFetch: on llvmpipe one vector gather, where a storage-buffer load is a loop over
// the lanes with a branch per lane and word (docs/lavapipe.md). Byte layouts are those
// of each structure's `to_gpu`; these helpers only address 16-, 8- and 4-byte units.
#ifndef ARBOR_ACCEL_TEXELS_GLSL
#define ARBOR_ACCEL_TEXELS_GLSL

layout(set = 0, binding = BINDING_ACCEL_NODES) uniform usamplerBuffer accel_node_texels;
layout(set = 0, binding = BINDING_ACCEL_INDICES) uniform usamplerBuffer accel_index_texels;

#ifdef HAS_INSTANCES
// Instanced scenes (common/instances.glsl): the structure being traversed is one of
// several in the buffers, from these texel offsets, over stored triangles from
// g_prim_base, inside g_box; its steps count against the whole trace's budget.
uint g_node_base = 0u;
uint g_index_base = 0u;
uint g_prim_base = 0u;
uint g_steps = 0u;
vec3 g_box_min = vec3(0.0);
vec3 g_box_max = vec3(0.0);
#define ACCEL_BOX_MIN g_box_min
#define ACCEL_BOX_MAX g_box_max
#define steps g_steps
#define STEPS_START
uvec4 node_texel(uint k) { return texelFetch(accel_node_texels, int(g_node_base + k)); }
uint accel_index(uint k) {
    return g_prim_base + texelFetch(accel_index_texels, int(g_index_base + (k >> 2u)))[k & 3u];
}
#else
// The box rays are first clipped to; the traversal's step counter.
#define ACCEL_BOX_MIN params.scene_min
#define ACCEL_BOX_MAX params.scene_max
#define STEPS_START uint steps = 0u
// 16-byte unit k of the node buffer.
uvec4 node_texel(uint k) { return texelFetch(accel_node_texels, int(k)); }
// Primitive index k.
uint accel_index(uint k) { return texelFetch(accel_index_texels, int(k >> 2u))[k & 3u]; }
#endif
// 8-byte unit k of the node buffer.
uvec2 node_pair(uint k) {
    uvec4 t = node_texel(k >> 1u);
    return (k & 1u) == 0u ? t.xy : t.zw;
}
// 4-byte word k of the node buffer.
uint node_word(uint k) { return node_texel(k >> 2u)[k & 3u]; }

#endif
