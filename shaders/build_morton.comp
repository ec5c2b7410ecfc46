#version 460
// 30-bit Morton codes of centroids in the centroid box, bit for bit as
// lbvh::MortonGrid on the CPU: scale = 1024 / extent correctly rounded (Vulkan's
// division is not, so the quotient is corrected with an exact residual), then
// (c - min) * scale truncated to 0..1023. Output: pairs[i] = (code, i); and for the
// climb of build_fit.comp, split i's arrival word aux[i].w = NONE (i < n - 1). Push: n.
#define USE_HEADER 1
#define USE_PRIM_BOUNDS 1
#define USE_PAIRS 1
#define USE_AUX 1
#include "common/ray.glsl"
#include "build/common.glsl"

layout(local_size_x = BUILD_GROUP) in;

// Correctly rounded 1024 / e for e > 0 (inf when that overflows, as IEEE division).
float scale_of(float e) {
    int ex;
    float m = frexp(e, ex); // e = m 2^ex, m in [0.5, 1)
    float q = 1024.0 / m;   // in (1024, 2048], a few ulps off at most
    uint qb = floatBitsToUint(q);
    float best = q;
    float best_err = 1e30;
    for (int d = -3; d <= 3; ++d) {
        float cand = uintBitsToFloat(uint(int(qb) + d));
        precise float p = cand * m;
        // cand m - 1024 exactly: p - 1024 is exact (Sterbenz), plus the product's error.
        precise float r = (p - 1024.0) + two_product_error(cand, m, p);
        if (abs(r) < best_err) {
            best_err = abs(r);
            best = cand;
        }
    }
    return ldexp(best, -ex);
}

uint quantise(float d, float s) {
    precise float x = d * s;
    if (!(x > 0.0)) return 0u;
    if (x >= 1023.0) return 1023u;
    return uint(x);
}

uint expand_bits(uint v) {
    uint x = v & 0x3ffu;
    x = (x | (x << 16u)) & 0x030000ffu;
    x = (x | (x << 8u)) & 0x0300f00fu;
    x = (x | (x << 4u)) & 0x030c30c3u;
    x = (x | (x << 2u)) & 0x09249249u;
    return x;
}

void main() {
    uint i = group_index() * BUILD_GROUP + gl_LocalInvocationID.x;
    if (i >= pc.n) return;
    vec3 bmin = vec3(order_float(hdr[BUILD_HDR_CMIN]), order_float(hdr[BUILD_HDR_CMIN + 1u]),
                     order_float(hdr[BUILD_HDR_CMIN + 2u]));
    vec3 bmax = vec3(order_float(hdr[BUILD_HDR_CMAX]), order_float(hdr[BUILD_HDR_CMAX + 1u]),
                     order_float(hdr[BUILD_HDR_CMAX + 2u]));
    precise vec3 c = (prim_bounds[2u * i].xyz + prim_bounds[2u * i + 1u].xyz) * 0.5;
    precise vec3 e = bmax - bmin;
    precise vec3 dd = c - bmin;
    uint q[3];
    for (uint k = 0u; k < 3u; ++k) {
        q[k] = e[k] > 0.0 ? quantise(dd[k], scale_of(e[k])) : 0u;
    }
    uint code = (expand_bits(q[0]) << 2u) | (expand_bits(q[1]) << 1u) | expand_bits(q[2]);
    pairs[i] = uvec2(code, i);
    if (i + 1u < pc.n) aux[i].w = NONE;
}
