// Counter-based random numbers: every draw is a pure function of (seed, pixel, sample, dimension),
// so any path can be replayed on the host (src/render/rng.rs mirrors this file bit for bit) and
// a path's draws do not depend on how many draws earlier vertices made.
//
// Hash: PCG-RXS-M-XS 32 as a hash (Jarzynski & Olano, "Hash Functions for GPU Rendering",
// JCGT 9(3), 2020), the function they recommend for quality per cost.
#ifndef TRILAB_RNG
#define TRILAB_RNG

uint pcg_hash(uint v) {
    uint state = v * 747796405u + 2891336453u;
    uint word = ((state >> ((state >> 28u) + 4u)) ^ state) * 277803737u;
    return (word >> 22u) ^ word;
}

// The key of one path: pixel `pixel` (y * width + x), sample `sample`, render seed `seed`.
uint path_key(uint seed, uint pixel, uint sample_index) {
    return pcg_hash(seed + pcg_hash(pixel + pcg_hash(sample_index)));
}

// Draw number `dim` of a path, as 32 random bits.
uint rand_u32(uint key, uint dim) {
    return pcg_hash(key + dim * 0x9E3779B9u);
}

// Draw number `dim` of a path, uniform in [0, 1): the top 24 bits, exactly representable.
float rand01(uint key, uint dim) {
    return float(rand_u32(key, dim) >> 8u) * (1.0 / 16777216.0);
}

#endif
