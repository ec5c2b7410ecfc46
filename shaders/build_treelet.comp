#version 460
// One round of treelet restructuring (Karras & Aila 2013), bit for bit as
// treelet::Restructure::round on the CPU. Each thread climbs from one leaf as in
// build_fit.comp; a node reached by the second thread, with at least gamma primitives
// below it, has both subtrees final and becomes a treelet root, which that thread
// optimises: the roots of each step are packed into the first lanes, and each lane
// optimises one on its own: it forms the treelet (expanding the largest-area treelet leaf
// until there are k), runs the dynamic programme over the leaf subsets in ascending
// order (every subset after its subsets), and writes the new topology if its cost is
// below cost * keep. A treelet reads and writes only its own subtree, so the result
// does not depend on scheduling. No subgroup operations: any subgroup size works.
// (One thread per treelet rather than the paper's one warp: llvmpipe runs barriers as
// coroutine switches, which made a workgroup-cooperative version 100x slower there.)
// Push: n, a = gamma, b = k (3..7 treelet leaves), ct, ci, keep.
#define USE_HEADER 1
#define USE_NODES 1
#include "build/common.glsl"

layout(local_size_x = BUILD_TREELET_GROUP) in;

const uint MAXK = 7u;
const uint SUBSETS = 1u << MAXK;

shared uint s_active;

float aux_cost(uint i) { return uintBitsToFloat(aux[i].z); }

// The box and primitive count of leaf subset s: the union folded from its highest
// leaf down, which is the CPU's order (box(S) = box(S without its lowest leaf) joined
// with the lowest leaf's), so the bits match.
// Per-thread tables of the treelet being solved: its leaves' boxes and counts, and the
// optimal cost of every leaf subset (leaf i alone at 1 << i).
vec3 llo[MAXK];
vec3 lhi[MAXK];
uint lcount[MAXK];
float copt[SUBSETS];

void subset_box(uint s, out vec3 lo, out vec3 hi, out uint count) {
    int h = findMSB(s);
    lo = llo[h];
    hi = lhi[h];
    count = lcount[h];
    uint t = s ^ (1u << uint(h));
    for (uint g = 0u; g < MAXK && t != 0u; ++g) {
        h = findMSB(t);
        lo = min(lo, llo[h]);
        hi = max(hi, lhi[h]);
        count += lcount[h];
        t ^= 1u << uint(h);
    }
}

// The cheapest split of subset s (two or more leaves) given the costs of its proper
// subsets: (cost sum, first part as float bits). Partitions (P, S \ P) with the lowest
// leaf in P: P = low | q, q a proper subset of the rest, descending, in the CPU's
// order; the first strictly cheapest wins; +inf and the lowest leaf when none is finite.
vec2 best_split(uint s) {
    uint low = s & (~s + 1u);
    uint rest = s ^ low;
    float best = uintBitsToFloat(0x7f800000u); // +inf
    uint best_p = low;
    uint q = (rest - 1u) & rest;
    for (uint g = 0u; g < SUBSETS; ++g) {
        uint p = low | q;
        precise float c = copt[p] + copt[s ^ p];
        if (c < best) {
            best = c;
            best_p = p;
        }
        if (q == 0u) break;
        q = (q - 1u) & rest;
    }
    return vec2(best, uintBitsToFloat(best_p));
}

void restructure(uint root) {
    uint leaf[MAXK];
    uint internal[MAXK - 1u];
    // Form the treelet.
    leaf[0] = node_left(root);
    leaf[1] = node_right(root);
    internal[0] = root;
    uint k = 2u;
    uint ni = 1u;
    for (uint g = 0u; g < MAXK && k < pc.b; ++g) {
        uint pick = NONE;
        float best = 0.0;
        for (uint slot = 0u; slot < k; ++slot) {
            uint l = leaf[slot];
            if (is_leaf(l)) continue;
            float a = box_area(node_min(l), node_max(l));
            if (pick == NONE || a > best) {
                pick = slot;
                best = a;
            }
        }
        if (pick == NONE) break;
        uint e = leaf[pick];
        internal[ni] = e;
        ni += 1u;
        leaf[pick] = node_left(e);
        leaf[k] = node_right(e);
        k += 1u;
    }
    if (k < 3u) return;
    // Dynamic programming over the subsets of the k leaves. Only the optimal costs are
    // kept per subset: llvmpipe gives private arrays per-lane scratch memory, set up
    // at every dispatch step, so a subset's box, count and best split are recomputed
    // where needed instead of stored (about a sixth of the scratch of storing them).
    for (uint i = 0u; i < k; ++i) {
        uint l = leaf[i];
        llo[i] = node_min(l);
        lhi[i] = node_max(l);
        lcount[i] = aux[l].y;
        copt[1u << i] = aux_cost(l);
    }
    uint full = (1u << k) - 1u;
    for (uint s = 3u; s <= full; ++s) {
        if (bitCount(s) < 2) continue;
        vec3 lo;
        vec3 hi;
        uint count;
        subset_box(s, lo, hi, count);
        copt[s] = node_cost(lo, hi, count, best_split(s).x);
    }
    precise float threshold = aux_cost(root) * pc.keep;
    if (!(copt[full] < threshold)) return;
    // Rebuild with the treelet's inner nodes, root first, in the CPU's order.
    uint stack_s[MAXK];
    uint stack_id[MAXK];
    uint sp = 1u;
    stack_s[0] = full;
    stack_id[0] = root;
    uint next = 1u;
    for (uint g = 0u; g < MAXK && sp > 0u; ++g) {
        sp -= 1u;
        uint s = stack_s[sp];
        uint id = stack_id[sp];
        uint a = floatBitsToUint(best_split(s).y);
        uint b = s ^ a;
        uint la;
        if (bitCount(a) == 1u) {
            la = leaf[findLSB(a)];
        } else {
            la = internal[next];
            next += 1u;
        }
        uint lb;
        if (bitCount(b) == 1u) {
            lb = leaf[findLSB(b)];
        } else {
            lb = internal[next];
            next += 1u;
        }
        vec3 lo;
        vec3 hi;
        uint count;
        subset_box(s, lo, hi, count);
        nodes[2u * id] = uvec4(floatBitsToUint(lo), la);
        nodes[2u * id + 1u] = uvec4(floatBitsToUint(hi), lb);
        aux[id].y = count;
        aux[id].z = floatBitsToUint(copt[s]);
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

shared uint s_mask[BUILD_TREELET_GROUP / 32u];
shared uint s_list[BUILD_TREELET_GROUP];

void main() {
    uint lid = gl_LocalInvocationID.x;
    uint j = group_index() * BUILD_TREELET_GROUP + lid;
    bool climbing = j < pc.n;
    uint cur = pc.n - 1u + j;
    // Every lane runs the atomic at every step, idle lanes on the spare entry 2n-1
    // (see build_fit.comp).
    uint spare = 2u * pc.n - 1u;
    uint word = lid / 32u;
    uint bit = 1u << (lid % 32u);
    bool done = false;
    for (uint step = 0u; step < BUILD_MAX_WALK; ++step) {
        uint p = climbing ? aux[cur].x : NONE;
        climbing = p != NONE;
        memoryBarrierBuffer();
        uint seen = atomicAdd(aux[climbing ? p : spare].w, 1u);
        climbing = climbing && seen != 0u;
        bool ready = false;
        if (climbing) {
            memoryBarrierBuffer();
            aux[p].w = 0u;
            cur = p;
            ready = aux[p].y >= pc.a;
        }
        if (lid < BUILD_TREELET_GROUP / 32u) s_mask[lid] = 0u;
        if (lid == 0u) s_active = 0u;
        barrier();
        if (ready) atomicOr(s_mask[word], bit);
        if (climbing) atomicAdd(s_active, 1u);
        barrier();
        // Pack this step's treelet roots into the first lanes, so that SIMD lanes
        // working together all have a treelet (the roots are disjoint subtrees).
        uint total = 0u;
        uint rank = 0u;
        for (uint w = 0u; w < BUILD_TREELET_GROUP / 32u; ++w) {
            uint c = bitCount(s_mask[w]);
            if (w < word) rank += c;
            total += c;
        }
        if (ready) s_list[rank + bitCount(s_mask[word] & (bit - 1u))] = cur;
        done = s_active == 0u;
        barrier();
        if (lid < total) {
            restructure(s_list[lid]);
            memoryBarrierBuffer();
        }
        barrier();
        if (done) break;
    }
    if (!done && lid == 0u) atomicOr(hdr[BUILD_HDR_ERRORS], BUILD_ERR_WALK);
}
