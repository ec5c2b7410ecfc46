// Counter-based random numbers: PCG hash (Jarzynski & Olano, "Hash Functions for GPU
// Rendering", JCGT 2020). A stream is keyed by (pixel, sample, seed), so results do
// not depend on how pixels and samples are split across dispatches.
#ifndef ARBOR_RNG_GLSL
#define ARBOR_RNG_GLSL

uint pcg_hash(uint v) {
    uint state = v * 747796405u + 2891336453u;
    uint word = ((state >> ((state >> 28u) + 4u)) ^ state) * 277803737u;
    return (word >> 22u) ^ word;
}

uint rng_init(uint pixel, uint sample_index, uint seed) {
    return pcg_hash(pixel ^ pcg_hash(sample_index ^ pcg_hash(seed)));
}

float rng_next(inout uint state) {
    state = pcg_hash(state);
    return float(state >> 8u) * (1.0 / 16777216.0);
}

#endif
