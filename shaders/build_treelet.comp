#version 460
// One height of one round of treelet restructuring (Karras & Aila 2013), bit for bit
// as treelet::Restructure::round on the CPU. build_levels.comp lists the round's
// treelet roots (inner nodes with at least gamma primitives below) by height; this
// kernel is dispatched once per height, lowest first, with one thread per root, so
// every treelet is optimised after the treelets below it. A thread forms the treelet
// (expanding the largest-area treelet leaf until there are k), runs the dynamic
// programme over the leaf subsets in ascending order (every subset after its
// subsets), and writes the new topology if its cost is below cost * keep. It then
// updates the heights in its subtree for the next round. A treelet reads and writes
// only its own subtree, so the result does not depend on scheduling. No subgroup
// operations: any subgroup size works. (One thread per treelet rather than the
// paper's one warp: llvmpipe runs barriers as coroutine switches, which made a
// workgroup-cooperative version 100x slower there. Dispatching by height rather than
// climbing from the leaves as build_fit.comp does: llvmpipe runs an if's body under a
// mask even when no lane is active, so a climbing kernel ran the treelet code at every
// step of every SIMD group.)
// Push: n, a = gamma, b = k (3..7 treelet leaves), c = height, ct, ci, keep.
#define USE_HEADER 1
#define USE_NODES 1
#define USE_LEVELS 1
#include "build/common.glsl"

layout(local_size_x = BUILD_TREELET_GROUP) in;

const uint MAXK = 7u;
const uint SUBSETS = 1u << MAXK;


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

// Height of inner node i from its children's (final by then).
void set_height(uint i) {
    levels[lv_height(i)] = 1u + max(levels[lv_height(node_left(i))], levels[lv_height(node_right(i))]);
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
    if (k < 3u) {
        set_height(root);
        return;
    }
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
    if (!(copt[full] < threshold)) {
        set_height(root);
        return;
    }
    // Rebuild with the treelet's inner nodes, root first, in the CPU's order.
    uint stack_s[MAXK];
    uint stack_id[MAXK];
    uint sp = 1u;
    stack_s[0] = full;
    stack_id[0] = root;
    uint next = 1u;
    uint written[MAXK - 1u];
    uint nw = 0u;
    for (uint g = 0u; g < MAXK && sp > 0u; ++g) {
        sp -= 1u;
        uint s = stack_s[sp];
        uint id = stack_id[sp];
        written[nw] = id;
        nw += 1u;
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
    // Heights bottom-up: a node is written before its children.
    for (uint w = nw; w > 0u; --w) set_height(written[w - 1u]);
}

void main() {
    uint t = group_index() * BUILD_TREELET_GROUP + gl_LocalInvocationID.x;
    uint h = pc.c;
    if (t < levels[LV_CURSOR + h]) restructure(levels[LV_LIST + levels[LV_OFFSET + h] + t]);
}
