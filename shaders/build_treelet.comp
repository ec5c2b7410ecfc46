#version 460
// One round of treelet restructuring (Karras & Aila 2013), bit for bit as
// treelet::Restructure::round on the CPU. Each thread climbs from one leaf as in
// build_fit.comp; a node reached by the second thread, with at least gamma primitives
// below it, has both subtrees final and becomes a treelet root. The workgroup then
// optimises its ready treelets one after another, all threads together: thread 0
// forms the treelet (expanding the largest-area treelet leaf until there are k), the
// dynamic programme runs over leaf subsets by size with one thread per subset and a
// barrier per size, and thread 0 writes the new topology if it is cheaper than
// cost * keep. Treelets ready at the same step are disjoint subtrees, so the result
// does not depend on scheduling. No subgroup operations: any subgroup size works.
// Push: n, a = gamma, b = k (3..7 treelet leaves), ct, ci, keep.
#define USE_HEADER 1
#define USE_NODES 1
#include "build/common.glsl"

layout(local_size_x = BUILD_TREELET_GROUP) in;

const uint MAXK = 7u;
const uint SUBSETS = 1u << MAXK;
// First index of the subsets of each size in s_order: sum of C(7, smaller sizes).
const uint SIZE_START[9] = uint[](0u, 1u, 8u, 29u, 64u, 99u, 120u, 127u, 128u);

shared uint s_order[SUBSETS]; // every 7-bit mask, ordered by popcount
shared uint s_ready[BUILD_TREELET_GROUP];
shared uint s_active;
shared uint s_leaf[MAXK];
shared uint s_internal[MAXK - 1u];
shared uint s_k;
shared float s_root_cost;
shared vec3 s_lo[SUBSETS];
shared vec3 s_hi[SUBSETS];
shared uint s_count[SUBSETS];
shared float s_copt[SUBSETS];
shared uint s_popt[SUBSETS];

float aux_cost(uint i) { return uintBitsToFloat(aux[i].z); }

void form_treelet(uint root) {
    s_leaf[0] = node_left(root);
    s_leaf[1] = node_right(root);
    s_internal[0] = root;
    uint k = 2u;
    uint ni = 1u;
    while (k < pc.b) {
        uint pick = NONE;
        float best = 0.0;
        for (uint slot = 0u; slot < k; ++slot) {
            uint l = s_leaf[slot];
            if (is_leaf(l)) continue;
            float a = box_area(node_min(l), node_max(l));
            if (pick == NONE || a > best) {
                pick = slot;
                best = a;
            }
        }
        if (pick == NONE) break;
        uint e = s_leaf[pick];
        s_internal[ni] = e;
        ni += 1u;
        s_leaf[pick] = node_left(e);
        s_leaf[k] = node_right(e);
        k += 1u;
    }
    s_k = k;
    s_root_cost = aux_cost(root);
    for (uint i = 0u; i < k; ++i) {
        uint l = s_leaf[i];
        uint m = 1u << i;
        s_lo[m] = node_min(l);
        s_hi[m] = node_max(l);
        s_count[m] = aux[l].y;
        s_copt[m] = aux_cost(l);
    }
}

void solve_subset(uint s) {
    uint low = s & (~s + 1u);
    uint rest = s ^ low;
    s_lo[s] = min(s_lo[rest], s_lo[low]);
    s_hi[s] = max(s_hi[rest], s_hi[low]);
    uint count = s_count[rest] + s_count[low];
    s_count[s] = count;
    // Partitions (P, S \ P) with the lowest leaf in P: P = low | q, q a proper subset
    // of the rest, in the CPU's order.
    float best = uintBitsToFloat(0x7f800000u); // +inf
    uint best_p = low;
    uint q = (rest - 1u) & rest;
    for (uint g = 0u; g < SUBSETS; ++g) {
        uint p = low | q;
        precise float c = s_copt[p] + s_copt[s ^ p];
        if (c < best) {
            best = c;
            best_p = p;
        }
        if (q == 0u) break;
        q = (q - 1u) & rest;
    }
    s_copt[s] = node_cost(s_lo[s], s_hi[s], count, best);
    s_popt[s] = best_p;
}

uint node_of(uint sub, inout uint next) {
    if (bitCount(sub) == 1u) return s_leaf[findLSB(sub)];
    uint id = s_internal[next];
    next += 1u;
    return id;
}

void write_topology(uint full) {
    uint stack_s[MAXK];
    uint stack_id[MAXK];
    uint sp = 1u;
    stack_s[0] = full;
    stack_id[0] = s_internal[0];
    uint next = 1u;
    for (uint g = 0u; g < MAXK && sp > 0u; ++g) {
        sp -= 1u;
        uint s = stack_s[sp];
        uint id = stack_id[sp];
        uint a = s_popt[s];
        uint b = s ^ a;
        uint la = node_of(a, next);
        uint lb = node_of(b, next);
        nodes[2u * id] = uvec4(floatBitsToUint(s_lo[s]), la);
        nodes[2u * id + 1u] = uvec4(floatBitsToUint(s_hi[s]), lb);
        aux[id].y = s_count[s];
        aux[id].z = floatBitsToUint(s_copt[s]);
        aux[la].x = id;
        aux[lb].x = id;
        if (bitCount(a) > 1u) {
            stack_s[sp] = a;
            stack_id[sp] = la;
            sp += 1u;
        }
        if (bitCount(b) > 1u) {
            stack_s[sp] = b;
            stack_id[sp] = lb;
            sp += 1u;
        }
    }
}

// Called by every thread of the workgroup with the same root.
void restructure(uint root) {
    uint lid = gl_LocalInvocationID.x;
    if (lid == 0u) form_treelet(root);
    barrier();
    uint k = s_k;
    if (k >= 3u) {
        for (uint size = 2u; size <= k; ++size) {
            for (uint slot = SIZE_START[size] + lid; slot < SIZE_START[size + 1u]; slot += BUILD_TREELET_GROUP) {
                uint s = s_order[slot];
                if ((s >> k) == 0u) solve_subset(s);
            }
            barrier();
        }
        uint full = (1u << k) - 1u;
        precise float threshold = s_root_cost * pc.keep;
        if (lid == 0u && s_copt[full] < threshold) write_topology(full);
        memoryBarrierBuffer();
    }
    barrier();
}

void main() {
    uint lid = gl_LocalInvocationID.x;
    // s_order: masks by popcount, then by value.
    for (uint m = lid; m < SUBSETS; m += BUILD_TREELET_GROUP) {
        uint pcount = bitCount(m);
        uint rank = 0u;
        for (uint o = 0u; o < m; ++o) rank += bitCount(o) == pcount ? 1u : 0u;
        s_order[SIZE_START[pcount] + rank] = m;
    }
    uint j = group_index() * BUILD_TREELET_GROUP + lid;
    bool climbing = j < pc.n;
    uint cur = pc.n - 1u + j;
    // Every lane runs the atomic at every step, idle lanes on the spare entry 2n-1
    // (see build_fit.comp).
    uint spare = 2u * pc.n - 1u;
    bool done = false;
    for (uint step = 0u; step < BUILD_MAX_WALK; ++step) {
        uint p = climbing ? aux[cur].x : NONE;
        climbing = p != NONE;
        memoryBarrierBuffer();
        uint seen = atomicAdd(aux[climbing ? p : spare].w, 1u);
        climbing = climbing && seen != 0u;
        uint ready = NONE;
        if (climbing) {
            memoryBarrierBuffer();
            aux[p].w = 0u;
            cur = p;
            if (aux[p].y >= pc.a) ready = p;
        }
        s_ready[lid] = ready;
        if (lid == 0u) s_active = 0u;
        barrier();
        if (climbing) atomicAdd(s_active, 1u);
        barrier();
        uint nactive = s_active;
        for (uint r = 0u; r < BUILD_TREELET_GROUP; ++r) {
            uint root = s_ready[r];
            if (root != NONE) restructure(root);
        }
        if (nactive == 0u) {
            done = true;
            break;
        }
        barrier();
    }
    if (!done && lid == 0u) atomicOr(hdr[BUILD_HDR_ERRORS], BUILD_ERR_WALK);
}
