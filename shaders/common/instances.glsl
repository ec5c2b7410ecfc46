// Two-level traversal for instanced scenes (HAS_INSTANCES), the layout of
// src/accel/instance.rs: a top-level BVH (the `bvh` node layout) over entries, each an
// instance of a prototype or the scene's own primitives, each with its own structure
// of the kernel's kind, traversed by the structure's own code (accel_closest /
// accel_any) after `inst_enter` points it at that structure and moves the ray into its
// space. inst_closest / inst_any are the scene's traces (trace.comp). Mirrors
// TwoLevel::traverse. Every step of both levels counts against the one budget,
// TREE_STEPS, beyond which the trace stops and is resumed (common/resume.glsl). The
// top level's state: the words INST_RS_* below (INST_RS_INSIDE: the next entry was
// stopped inside, and its structure saved the bottom level at RS_LEVEL); the stack
// from RESUME_LEVEL_WORDS.
#ifndef ARBOR_INSTANCES_GLSL
#define ARBOR_INSTANCES_GLSL

#define INST_RS_CUR 0u
#define INST_RS_SP 1u
#define INST_RS_FOUND 2u
#define INST_RS_K_FIRST 3u  // the entries of leaf cur already done
#define INST_RS_INSIDE 4u
#define INST_RESUME_WORDS 5
#if INST_RESUME_WORDS > RESUME_LEVEL_WORDS
#error "the top level's resume words exceed RESUME_LEVEL_WORDS"
#endif

#ifdef ACCEL_RAYQUERY
// The driver's structure traverses both levels (accel/rayquery.glsl); only the
// records' readers below are used.
#include "common/accel_texels.glsl"
#else
#include "common/bvh_leaf.glsl"
#endif

// INST_ENTRY_TEXELS, INST_ENTRY_OWN: src/gpu/bindings.rs.

// Texel k of the node buffer, from its start.
uvec4 inst_texel(uint k) { return texelFetch(accel_node_texels, int(k)); }
// First texel of entry e's record.
uint inst_record(uint e) { return inst_texel(0u).z + e * INST_ENTRY_TEXELS; }

#ifndef ACCEL_RAYQUERY
// Points the bottom-level traversal at entry e's structure and returns `r` in its
// space: origin and direction by the world-to-object transform, not renormalised, so
// that t is the same in both spaces.
Ray inst_enter(uint e, Ray r) {
    uint base = inst_record(e);
    uvec4 refs = inst_texel(base + 6u);
    uvec4 lo = inst_texel(base + 7u);
    g_node_base = refs.x;
    g_index_base = refs.y;
    g_prim_base = refs.z;
    g_box_min = uintBitsToFloat(lo.xyz);
    g_box_max = uintBitsToFloat(inst_texel(base + 8u).xyz);
    if ((lo.w & INST_ENTRY_OWN) != 0u) return r;
    vec4 m0 = uintBitsToFloat(inst_texel(base));
    vec4 m1 = uintBitsToFloat(inst_texel(base + 1u));
    vec4 m2 = uintBitsToFloat(inst_texel(base + 2u));
    Ray o = r;
    o.origin = vec3(dot(m0.xyz, r.origin) + m0.w, dot(m1.xyz, r.origin) + m1.w, dot(m2.xyz, r.origin) + m2.w);
    o.dir = vec3(dot(m0.xyz, r.dir), dot(m1.xyz, r.dir), dot(m2.xyz, r.dir));
    return o;
}

bool inst_traverse(Ray r, inout Hit h, bool any_hit) {
    vec3 inv = safe_rcp3(r.dir);
    float e0, e1;
    if (!ray_box(params.scene_min, params.scene_max, r.origin, inv, r.tmin, r.tmax, e0, e1)) return false;
    uvec4 hdr = inst_texel(0u);
    uint stack[STACK_SIZE];
    uint sp = 0u;
    uint cur = 0u;
    bool found = false;
    g_steps = 0u;
    uint k_first = 0u;
    bool inside = false;
    if (RESUME_PASS && g_resuming) {
        cur = rs_get(INST_RS_CUR);
        sp = rs_get(INST_RS_SP);
        found = rs_get(INST_RS_FOUND) != 0u;
        k_first = rs_get(INST_RS_K_FIRST);
        for (uint q = 0u; q < sp; q++) stack[q] = rs_get(RESUME_LEVEL_WORDS + q);
        // The bottom level restores its own state when it was stopped inside.
        g_resuming = rs_get(INST_RS_INSIDE) != 0u;
    }
    while (g_steps < TREE_STEPS) {
        while ((cur & BVH_LEAF) == 0u && g_steps < TREE_STEPS) {
            g_steps += 1u;
            g_nodes += 1u;
            uint n = hdr.x + 4u * cur;
            BVH_NODE_STEP(inst_texel, n)
        }
        if ((cur & BVH_LEAF) == 0u) break;
        uint first = bvh_leaf_first(cur);
        uint count = bvh_leaf_count(cur);
        uint k = k_first;
        for (; k < count && g_steps < TREE_STEPS; k++) {
            // An entry costs the passes its structure's loops make even when they do
            // nothing (llvmpipe counts those too), besides the steps they take.
            g_steps += INST_ENTRY_STEPS;
            uint w = hdr.y * 4u + first + k;
            uint e = inst_texel(w >> 2u)[w & 3u];
            Ray o = inst_enter(e, r);
            g_level = RS_LEVEL;
            bool hit;
            if (any_hit) {
                hit = accel_any(o);
            } else {
                hit = accel_closest(o, h);
            }
            g_level = 0u;
            if (g_suspended) {
                inside = true;
                break;
            }
            if (hit) {
                if (any_hit) return true;
                found = true;
                h.inst = e;
            }
        }
        // A leaf cut short (by the step budget, or inside an entry) resumes at that entry.
        if (k < count) {
            k_first = k;
            break;
        }
        k_first = 0u;
        if (sp == 0u) return found;
        sp -= 1u;
        cur = stack[sp];
    }
    if (trace_suspend()) {
        rs_put(INST_RS_CUR, cur);
        rs_put(INST_RS_SP, sp);
        rs_put(INST_RS_FOUND, uint(found));
        rs_put(INST_RS_K_FIRST, k_first);
        rs_put(INST_RS_INSIDE, uint(inside));
        for (uint q = 0u; q < sp; q++) rs_put(RESUME_LEVEL_WORDS + q, stack[q]);
    }
    return found;
}

bool inst_closest(Ray r, inout Hit h) { return inst_traverse(r, h, false); }
bool inst_any(Ray r) {
    Hit h;
    h.t = r.tmax; h.prim = NO_PRIM; h.u = 0.0; h.v = 0.0; h.inst = 0u;
    return inst_traverse(r, h, true);
}
#endif

// A hit on an instance, computed in its prototype's space, into the world: the point
// by the object-to-world transform, its error bound carried through |M| plus the
// rounding of the transform itself (pbrt-v4's transformed-point bound, with gamma(5)
// for margin), normals by the inverse transpose.
void inst_to_world(Hit h, inout vec3 p, inout vec3 err, inout vec3 gn, inout vec3 sn) {
    uint base = inst_record(h.inst);
    if ((inst_texel(base + 7u).w & INST_ENTRY_OWN) != 0u) return;
    vec4 w0 = uintBitsToFloat(inst_texel(base));
    vec4 w1 = uintBitsToFloat(inst_texel(base + 1u));
    vec4 w2 = uintBitsToFloat(inst_texel(base + 2u));
    vec4 o0 = uintBitsToFloat(inst_texel(base + 3u));
    vec4 o1 = uintBitsToFloat(inst_texel(base + 4u));
    vec4 o2 = uintBitsToFloat(inst_texel(base + 5u));
    vec3 po = p;
    vec3 ap = abs(po);
    p = vec3(dot(o0.xyz, po) + o0.w, dot(o1.xyz, po) + o1.w, dot(o2.xyz, po) + o2.w);
    precise vec3 carried = vec3(dot(abs(o0.xyz), err), dot(abs(o1.xyz), err), dot(abs(o2.xyz), err));
    precise vec3 own = vec3(dot(abs(o0.xyz), ap) + abs(o0.w), dot(abs(o1.xyz), ap) + abs(o1.w),
                            dot(abs(o2.xyz), ap) + abs(o2.w));
    err = (carried + GAMMA_5 * own) * (1.0 + GAMMA_5);
    gn = normalize(w0.xyz * gn.x + w1.xyz * gn.y + w2.xyz * gn.z);
    sn = normalize(w0.xyz * sn.x + w1.xyz * sn.y + w2.xyz * sn.z);
}

// The hit's number in the flattened scene: own triangles, then each instance's copy
// of its prototype's triangles, then the spheres.
uint inst_aov_prim(Hit h) {
    uvec4 counts = inst_texel(1u);
    uint base = inst_record(h.inst);
    if ((inst_texel(base + 7u).w & INST_ENTRY_OWN) != 0u) {
        if (h.prim < params.triangle_count) return h.prim - counts.x;
        return h.prim - params.triangle_count + counts.y + counts.z;
    }
    return counts.y + inst_texel(base + 6u).w + (h.prim - inst_texel(base + 6u).z);
}

#endif
