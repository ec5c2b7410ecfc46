// 4-wide BVH traversal (bvh4). Mirrors traverse_wide in src/accel/bvh/wide.rs, where
// the layout is documented: 7 texels per node, the four children's boxes as
// structure of arrays (min x, min y, min z, max x, max y, max z) and their references
// (the binary BVH's encoding: bit 31 leaf, first << 3 | count - 1; 0xffffffff none).
//
// Front to back: the four boxes are tested against [tmin, best t (1 + 1e-5)], the
// hit children sorted by entry distance with a five-comparator network, the nearest
// visited and the others pushed, farthest first. The pushes are unconditional writes
// followed by a conditional increment (no branch per child); the stack therefore
// holds 3 x depth + 1 entries (STACK_SIZE, set at build time). Inner nodes are
// descended in an inner loop and leaves tested after it ("while-while"); every trace
// takes at most TREE_STEPS steps (nodes + primitive tests), beyond which it stops and
// is resumed with the state of bvh.glsl (BVH_RESTORE, common/bvh_leaf.glsl).

#define ACCEL_RESUMABLE 1
#include "common/bvh_leaf.glsl"

bool bvh4_traverse(Ray r, inout Hit h, bool any_hit) {
    vec3 inv = safe_rcp3(r.dir);
    float e0, e1;
    if (!ray_box(ACCEL_BOX_MIN, ACCEL_BOX_MAX, r.origin, inv, r.tmin, r.tmax, e0, e1)) return false;
    const float INF = uintBitsToFloat(0x7f800000u);
    uint stack[STACK_SIZE];
    uint sp = 0u;
    uint cur = 0u;
    bool found = false;
    STEPS_START;
    BVH_RESTORE;
    while (steps < TREE_STEPS) {
        while ((cur & BVH_LEAF) == 0u && steps < TREE_STEPS) {
            steps += 1u;
            g_nodes += 1u;
            uint base = WIDE_NODE_PLANES * cur;
            vec4 lx = uintBitsToFloat(node_texel(base));
            vec4 ly = uintBitsToFloat(node_texel(base + 1u));
            vec4 lz = uintBitsToFloat(node_texel(base + 2u));
            vec4 hx = uintBitsToFloat(node_texel(base + 3u));
            vec4 hy = uintBitsToFloat(node_texel(base + 4u));
            vec4 hz = uintBitsToFloat(node_texel(base + 5u));
            uvec4 refs = node_texel(base + 6u);
            precise float limit = h.t * (1.0 + BVH_T_MARGIN);
            float k0 = wide_enter(refs.x, vec3(lx.x, ly.x, lz.x), vec3(hx.x, hy.x, hz.x), r, inv, limit);
            float k1 = wide_enter(refs.y, vec3(lx.y, ly.y, lz.y), vec3(hx.y, hy.y, hz.y), r, inv, limit);
            float k2 = wide_enter(refs.z, vec3(lx.z, ly.z, lz.z), vec3(hx.z, hy.z, hz.z), r, inv, limit);
            float k3 = wide_enter(refs.w, vec3(lx.w, ly.w, lz.w), vec3(hx.w, hy.w, hz.w), r, inv, limit);
            uint r0 = refs.x, r1 = refs.y, r2 = refs.z, r3 = refs.w;
            uint n = uint(k0 < INF) + uint(k1 < INF) + uint(k2 < INF) + uint(k3 < INF);
            wide_swap(k0, r0, k1, r1);
            wide_swap(k2, r2, k3, r3);
            wide_swap(k0, r0, k2, r2);
            wide_swap(k1, r1, k3, r3);
            wide_swap(k1, r1, k2, r2);
            stack[sp] = r3;
            sp += n > 3u ? 1u : 0u;
            stack[sp] = r2;
            sp += n > 2u ? 1u : 0u;
            stack[sp] = r1;
            sp += n > 1u ? 1u : 0u;
            if (n > 0u) {
                cur = r0;
            } else {
                if (sp == 0u) return found;
                sp -= 1u;
                cur = stack[sp];
            }
        }
        if ((cur & BVH_LEAF) == 0u) break;
        uint tested = steps;
        if (bvh_leaf(cur, r, h, any_hit, true, steps)) {
            found = true;
            if (any_hit) return true;
        }
        BVH_LEAF_CUT(tested);
        if (sp == 0u) return found;
        sp -= 1u;
        cur = stack[sp];
    }
    BVH_SUSPEND;
    return found;
}

bool trace_closest(Ray r, inout Hit h) {
    return bvh4_traverse(r, h, false);
}

bool trace_any(Ray r) {
    Hit h;
    h.t = r.tmax; h.prim = NO_PRIM; h.u = 0.0; h.v = 0.0;
    return bvh4_traverse(r, h, true);
}
