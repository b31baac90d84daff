// Sampler points for many samplers at once: Sampler::get2D's arithmetic over arrays, so that it runs in SIMD
// lanes (integer operations only, so the bits are those of the one-at-a-time calls).
#include "baker/render/sampler.h"

#include <algorithm>

namespace nrad {

// x86-64: a clone for AVX2 and one for AVX-512 (8 and 16 lanes with a 32-bit multiply; baseline SSE2 has none,
// and its loops are no faster than the calls), chosen at load time by the CPU.
// (NRAD_NO_TARGET_CLONES: the default alone, for its test.)
#if defined(__x86_64__) && defined(__GNUC__) && !defined(__clang__) && !defined(NRAD_NO_TARGET_CLONES)
__attribute__((target_clones("avx512f", "avx2", "default")))
#endif
void next2D(Sampler* const* samplers, size_t n, uint32_t count, glm::vec2* out) {
    constexpr size_t kChunk = 64;
    uint32_t stream[kChunk], indexReversed[kChunk], dimension[kChunk], seed[kChunk], i[kChunk], x[kChunk], y[kChunk];
    for (size_t first = 0; first < n; first += kChunk) {
        const size_t m = std::min(kChunk, n - first);
        for (size_t k = 0; k < m; ++k) {
            const Sampler& s = *samplers[first + k];
            stream[k] = s.stream_;
            indexReversed[k] = s.indexReversed_;
            dimension[k] = s.dimension_;
        }
        for (uint32_t j = 0; j < count; ++j) {
            // Sampler::get2D over the chunk, in integer operations that all vectorise.
            for (size_t k = 0; k < m; ++k) {
                seed[k] = hashCombine(stream[k], dimension[k] + j);
                i[k] = reverseBits(laineKarrasPermutation(indexReversed[k], seed[k]));
                x[k] = reverseBits(laineKarrasPermutation(i[k], seed[k] * 0x9e3779b9u + 0x632be5abu));
                y[k] = reverseBits(laineKarrasPermutation(sobolDim1Reversed(i[k]), seed[k] * 0x85ebca6bu + 0x2c1b3c6du));
            }
            for (size_t k = 0; k < m; ++k) out[count * (first + k) + j] = glm::vec2(toUnitFloat(x[k]), toUnitFloat(y[k]));
        }
        for (size_t k = 0; k < m; ++k) samplers[first + k]->dimension_ += count;
    }
}

}  // namespace nrad
