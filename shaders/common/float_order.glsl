// Order-preserving map of floats to uints, for atomicMin / atomicMax of float bounds
// (the GPU BVH builder's centroid box, the photon grid's box), and back. Negative
// floats flip every bit, others set the sign bit: -1.0 (0xbf800000) maps to
// 0x407fffff, below 0.0's 0x80000000, below 1.0's 0xbf800000.
#ifndef ARBOR_FLOAT_ORDER_GLSL
#define ARBOR_FLOAT_ORDER_GLSL

uint float_order(float f) {
    uint b = floatBitsToUint(f);
    return (b & 0x80000000u) != 0u ? ~b : (b | 0x80000000u);
}
float order_float(uint u) {
    return uintBitsToFloat((u & 0x80000000u) != 0u ? (u & 0x7fffffffu) : ~u);
}

#endif
