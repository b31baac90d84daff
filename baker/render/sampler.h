// Quasi-Monte Carlo sampler: Owen-scrambled Sobol points (hash-based nested uniform scrambling, Burley
// 2020, "Practical Hash-based Owen Scrambling"), padded across dimensions by shuffling the index per
// dimension. Each pixel (or sample stream) gets its own seed, so pixels are decorrelated and every
// sample is reproducible from (seed, stream, index) alone: no state is shared between threads.
#pragma once

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
inline uint32_t sobolDim1(uint32_t index) {
    uint32_t result = 0;
    for (uint32_t v = 1u << 31; index; index >>= 1, v ^= v >> 1)
        if (index & 1u) result ^= v;
    return result;
}

inline float toUnitFloat(uint32_t x) { return float(x >> 8) * 0x1p-24f; }  // in [0, 1)

class Sampler {
public:
    // stream: e.g. a hash of the pixel; index: the sample number within that stream.
    Sampler(uint32_t stream, uint32_t index) : stream_(stream), index_(index) {}

    float get1D() {
        uint32_t seed = hashCombine(stream_, dimension_++);
        uint32_t i = nestedUniformScramble(index_, hashCombine(seed, 0x5eed0u));
        return toUnitFloat(nestedUniformScramble(sobolDim0(i), hashCombine(seed, 1u)));
    }

    glm::vec2 get2D() {
        uint32_t seed = hashCombine(stream_, dimension_++);
        uint32_t i = nestedUniformScramble(index_, hashCombine(seed, 0x5eed0u));
        return {toUnitFloat(nestedUniformScramble(sobolDim0(i), hashCombine(seed, 1u))),
                toUnitFloat(nestedUniformScramble(sobolDim1(i), hashCombine(seed, 2u)))};
    }

    uint32_t dimension() const { return dimension_; }

private:
    uint32_t stream_;
    uint32_t index_;
    uint32_t dimension_ = 0;
};

// Stream id of a pixel for a given user seed.
inline uint32_t pixelStream(uint32_t x, uint32_t y, uint32_t seed) {
    return hashCombine(hashCombine(hashU32(seed), x), y);
}

}  // namespace nrad
