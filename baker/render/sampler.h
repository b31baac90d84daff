// Quasi-Monte Carlo sampler: Owen-scrambled Sobol points (hash-based nested uniform scrambling, Burley
// 2020, "Practical Hash-based Owen Scrambling"), padded across dimensions by shuffling the index per
// dimension. Each pixel (or sample stream) gets its own seed, so pixels are decorrelated and every
// sample is reproducible from (seed, stream, index) alone: no state is shared between threads.
#pragma once

#include <cstddef>
#include <cstdint>

#include <glm/glm.hpp>

namespace nrad {

inline uint32_t reverseBits(uint32_t x) {
    x = (x << 16) | (x >> 16);
    x = ((x & 0x00ff00ffu) << 8) | ((x & 0xff00ff00u) >> 8);
    x = ((x & 0x0f0f0f0fu) << 4) | ((x & 0xf0f0f0f0u) >> 4);
    x = ((x & 0x33333333u) << 2) | ((x & 0xccccccccu) >> 2);
    x = ((x & 0x55555555u) << 1) | ((x & 0xaaaaaaaau) >> 1);
    return x;
}

// A good 32-bit integer hash (lowbias32, Chris Wellons).
inline uint32_t hashU32(uint32_t x) {
    x ^= x >> 16;
    x *= 0x7feb352du;
    x ^= x >> 15;
    x *= 0x846ca68bu;
    x ^= x >> 16;
    return x;
}

inline uint32_t hashCombine(uint32_t seed, uint32_t v) { return hashU32(seed ^ (v + 0x9e3779b9u + (seed << 6) + (seed >> 2))); }

inline uint32_t laineKarrasPermutation(uint32_t x, uint32_t seed) {
    x += seed;
    x ^= x * 0x6c50b47cu;
    x ^= x * 0xb82f1e52u;
    x ^= x * 0xc7afe638u;
    x ^= x * 0x8d22f6e6u;
    return x;
}

// Owen scrambling of a 32-bit fixed-point value in [0,1).
inline uint32_t nestedUniformScramble(uint32_t x, uint32_t seed) {
    return reverseBits(laineKarrasPermutation(reverseBits(x), seed));
}

// First two Sobol dimensions as 32-bit fixed point.
inline uint32_t sobolDim0(uint32_t index) { return reverseBits(index); }

// The second dimension, bit reversed (what Owen scrambling works on). Its direction numbers are the rows of
// Pascal's triangle mod 2 (v_k = v_{k-1} ^ (v_{k-1} >> 1)): bit j of the reversed value is the parity of
// binomial(k, j) over the index's set bits k, and by Lucas' theorem binomial(k, j) is odd exactly where j's
// bits are a subset of k's. So bit j is the XOR of the index's bits at the supersets of j: five steps, each
// folding in the positions one bit of j higher, in shifts and masks that vectorise (no table lookups).
inline uint32_t sobolDim1Reversed(uint32_t index) {
    uint32_t y = index;
    y ^= (y >> 1) & 0x55555555u;
    y ^= (y >> 2) & 0x33333333u;
    y ^= (y >> 4) & 0x0f0f0f0fu;
    y ^= (y >> 8) & 0x00ff00ffu;
    y ^= (y >> 16) & 0x0000ffffu;
    return y;
}
inline uint32_t sobolDim1(uint32_t index) { return reverseBits(sobolDim1Reversed(index)); }

inline float toUnitFloat(uint32_t x) { return float(x >> 8) * 0x1p-24f; }  // in [0, 1)

class Sampler {
public:
    // stream: e.g. a hash of the pixel; index: the sample number within that stream.
    Sampler(uint32_t stream, uint32_t index) : stream_(stream), indexReversed_(reverseBits(index)) {}

    // The same bits as the plain nested scrambles (sampler_test.cpp), with fewer bit reversals: the index's
    // is done once per sampler; dimension 0 of Sobol is the bit reversal of the index, so its Owen scramble
    // reverseBits(LK(reverseBits(reverseBits(i)))) is reverseBits(LK(i)); and dimension 1 comes from a table
    // of reversed direction numbers, ready for its scramble.
    float get1D() {
        uint32_t seed = hashCombine(stream_, dimension_++);
        uint32_t i = reverseBits(laineKarrasPermutation(indexReversed_, seed));
        return toUnitFloat(reverseBits(laineKarrasPermutation(i, seed * 0x9e3779b9u + 0x632be5abu)));
    }

    glm::vec2 get2D() {
        // One hash per dimension pair; the three scrambles get distinct seeds by odd multipliers (the
        // Laine-Karras permutation mixes them thoroughly).
        uint32_t seed = hashCombine(stream_, dimension_++);
        uint32_t i = reverseBits(laineKarrasPermutation(indexReversed_, seed));
        return {toUnitFloat(reverseBits(laineKarrasPermutation(i, seed * 0x9e3779b9u + 0x632be5abu))),
                toUnitFloat(reverseBits(laineKarrasPermutation(sobolDim1Reversed(i), seed * 0x85ebca6bu + 0x2c1b3c6du)))};
    }

    uint32_t dimension() const { return dimension_; }

private:
    friend struct SamplerState;  // next2D's (sampler.cpp)
    uint32_t stream_;
    uint32_t indexReversed_;
    uint32_t dimension_ = 0;
};

// `count` consecutive get2D() of each of samplers[0..n) at once, out[count k + j] the j-th of samplers[k]
// (each advanced by `count` dimension pairs): the same bits as the calls, in loops the compiler vectorises
// across samplers (the path tracer's batches draw their camera jitters and vertices' 2D points this way).
// On x86-64 machines with AVX-512 and GFNI (Ice Lake, Zen 4 on) an AVX-512 kernel whose bit reversals are one
// GFNI instruction each does it; elsewhere the compiler's vectorisation of the plain code (AVX2 / AVX-512 clones).
void next2D(Sampler* const* samplers, size_t n, uint32_t count, glm::vec2* out);
// next2D without its GFNI kernel: what machines without GFNI run (for tests on machines that have it).
void next2DWithoutGfni(Sampler* const* samplers, size_t n, uint32_t count, glm::vec2* out);

// Stream id of a pixel for a given user seed.
inline uint32_t pixelStream(uint32_t x, uint32_t y, uint32_t seed) {
    return hashCombine(hashCombine(hashU32(seed), x), y);
}

}  // namespace nrad
