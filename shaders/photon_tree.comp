#version 460
// For tests and the benchmark: photons looked up in the kd-tree over visible points
// (common/photon_tree.glsl, as the photon pass will), one invocation a photon. Push:
// x the tree's nodes, y the photons. Output: the points found and the sum of their
// indices + 1, per photon.
#extension GL_GOOGLE_include_directive : require

layout(local_size_x = PHOTON_GROUP) in;

layout(push_constant) uniform TreePush {
    uint nodes;
    uint photons;
    uint unused0;
    uint unused1;
} pc;

layout(std430, set = 0, binding = BINDING_PHOTON_TREE) readonly buffer TreeNodes { vec4 tree_nodes[]; };
layout(std430, set = 0, binding = BINDING_PHOTON_POINTS) readonly buffer TreePoints { vec4 points[]; };
layout(std430, set = 0, binding = BINDING_PHOTON_QUERIES) readonly buffer TreeQueries { vec4 queries[]; };
layout(std430, set = 0, binding = BINDING_PHOTON_FOUND) writeonly buffer TreeFound { uvec2 found[]; };

#define PHOTON_TREE_STACK PHOTON_TREE_MAX_DEPTH
#define PHOTON_TREE_NODE(i) tree_nodes[i]
#define PHOTON_POINT(v) points[v]
#include "common/photon_tree.glsl"

uvec2 g_found = uvec2(0u);
void photon_visit(uint v, vec3 p) { g_found += uvec2(1u, v + 1u); }

void main() {
    uint i = gl_GlobalInvocationID.x;
    if (i >= pc.photons) return;
    tree_walk(queries[i].xyz, pc.nodes);
    found[i] = g_found;
}
