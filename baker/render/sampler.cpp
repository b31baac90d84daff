// Sampler points for many samplers at once: Sampler::get2D's arithmetic over arrays, so that it runs in SIMD
// lanes (integer operations only, so the bits are those of the one-at-a-time calls).
#include "baker/render/sampler.h"

#include <algorithm>

// x86-64 with GCC: besides the compiler's vectorisation (clones below), an AVX-512 kernel written out with GFNI's
// affine byte transform, which reverses a byte's bits in one instruction (the Owen scramble reverses three words
// per point, otherwise in five shift-and-mask steps each). NRAD_NO_TARGET_CLONES: the default alone, for its test.
#if defined(__x86_64__) && defined(__GNUC__) && !defined(__clang__) && !defined(NRAD_NO_TARGET_CLONES)
#define NRAD_SAMPLER_GFNI 1
#include <immintrin.h>
#endif

namespace nrad {

struct SamplerState {
    static uint32_t stream(const Sampler& s) { return s.stream_; }
    static uint32_t indexReversed(const Sampler& s) { return s.indexReversed_; }
    static void advance(Sampler& s, uint32_t count) { s.dimension_ += count; }
};

namespace {

constexpr size_t kChunk = 64;

// next2D's frame: the samplers in chunks of kChunk, their state in arrays, and for each draw j the chunk's points
// from `points(stream, indexReversed, dimension, j, m, x, y)` (get2D's scrambled words for lanes [0, m)).
template <class Points>
inline __attribute__((always_inline)) void drawChunks(Sampler* const* samplers, size_t n, uint32_t count, glm::vec2* out,
                                                     Points points) {
    alignas(64) uint32_t stream[kChunk], indexReversed[kChunk], dimension[kChunk], x[kChunk], y[kChunk];
    for (size_t first = 0; first < n; first += kChunk) {
        const size_t m = std::min(kChunk, n - first);
        for (size_t k = 0; k < m; ++k) {
            const Sampler& s = *samplers[first + k];
            stream[k] = SamplerState::stream(s);
            indexReversed[k] = SamplerState::indexReversed(s);
            dimension[k] = s.dimension();
        }
        for (uint32_t j = 0; j < count; ++j) {
            points(stream, indexReversed, dimension, j, m, x, y);
            for (size_t k = 0; k < m; ++k) out[count * (first + k) + j] = glm::vec2(toUnitFloat(x[k]), toUnitFloat(y[k]));
        }
        for (size_t k = 0; k < m; ++k) SamplerState::advance(*samplers[first + k], count);
    }
}

// Sampler::get2D over a chunk, in integer operations that all vectorise.
struct PlainPoints {
    inline __attribute__((always_inline)) void operator()(const uint32_t* stream, const uint32_t* indexReversed,
                                                         const uint32_t* dimension, uint32_t j, size_t m, uint32_t* x,
                                                         uint32_t* y) const {
        for (size_t k = 0; k < m; ++k) {
            const uint32_t seed = hashCombine(stream[k], dimension[k] + j);
            const uint32_t i = reverseBits(laineKarrasPermutation(indexReversed[k], seed));
            x[k] = reverseBits(laineKarrasPermutation(i, seed * 0x9e3779b9u + 0x632be5abu));
            y[k] = reverseBits(laineKarrasPermutation(sobolDim1Reversed(i), seed * 0x85ebca6bu + 0x2c1b3c6du));
        }
    }
};

#ifdef NRAD_SAMPLER_GFNI
#define NRAD_GFNI_TARGET __attribute__((target("avx512f,avx512bw,gfni"), always_inline))

// The same operations as PlainPoints, sixteen lanes per instruction.
struct GfniPoints {
    // The zero-masked forms of the shifts and shuffles: their plain forms pass an undefined vector through,
    // which GCC 12's link-time optimisation reports as maybe uninitialised.
    static constexpr __mmask16 kAll = __mmask16(0xffff);
    static inline NRAD_GFNI_TARGET __m512i srl(__m512i v, unsigned n) { return _mm512_maskz_srli_epi32(kAll, v, n); }
    static inline NRAD_GFNI_TARGET __m512i sll(__m512i v, unsigned n) { return _mm512_maskz_slli_epi32(kAll, v, n); }
    static inline NRAD_GFNI_TARGET __m512i reverse(__m512i v) {
        // Each byte's bits reversed (the affine transform by the anti-diagonal bit matrix), then each word's bytes.
        v = _mm512_gf2p8affine_epi64_epi8(v, _mm512_set1_epi64(0x8040201008040201ll), 0);
        const __m128i bytes = _mm_setr_epi8(3, 2, 1, 0, 7, 6, 5, 4, 11, 10, 9, 8, 15, 14, 13, 12);
        return _mm512_maskz_shuffle_epi8(~__mmask64(0), v, _mm512_maskz_broadcast_i32x4(kAll, bytes));
    }
    static inline NRAD_GFNI_TARGET __m512i mul(__m512i v, uint32_t c) {
        return _mm512_mullo_epi32(v, _mm512_set1_epi32(int(c)));
    }
    static inline NRAD_GFNI_TARGET __m512i add(__m512i v, uint32_t c) {
        return _mm512_add_epi32(v, _mm512_set1_epi32(int(c)));
    }
    static inline NRAD_GFNI_TARGET __m512i hash(__m512i v) {  // hashU32
        v = _mm512_xor_si512(v, srl(v, 16));
        v = mul(v, 0x7feb352du);
        v = _mm512_xor_si512(v, srl(v, 15));
        v = mul(v, 0x846ca68bu);
        return _mm512_xor_si512(v, srl(v, 16));
    }
    static inline NRAD_GFNI_TARGET __m512i laineKarras(__m512i v, __m512i seed) {
        v = _mm512_add_epi32(v, seed);
        v = _mm512_xor_si512(v, mul(v, 0x6c50b47cu));
        v = _mm512_xor_si512(v, mul(v, 0xb82f1e52u));
        v = _mm512_xor_si512(v, mul(v, 0xc7afe638u));
        return _mm512_xor_si512(v, mul(v, 0x8d22f6e6u));
    }
    static inline NRAD_GFNI_TARGET __m512i sobol1(__m512i v) {  // sobolDim1Reversed
        v = _mm512_xor_si512(v, _mm512_and_si512(srl(v, 1), _mm512_set1_epi32(0x55555555)));
        v = _mm512_xor_si512(v, _mm512_and_si512(srl(v, 2), _mm512_set1_epi32(0x33333333)));
        v = _mm512_xor_si512(v, _mm512_and_si512(srl(v, 4), _mm512_set1_epi32(0x0f0f0f0f)));
        v = _mm512_xor_si512(v, _mm512_and_si512(srl(v, 8), _mm512_set1_epi32(0x00ff00ff)));
        return _mm512_xor_si512(v, _mm512_and_si512(srl(v, 16), _mm512_set1_epi32(0x0000ffff)));
    }
    // Not inlined into drawChunks (compiled for the baseline target): one call per chunk and draw.
    __attribute__((target("avx512f,avx512bw,gfni"))) void operator()(const uint32_t* stream,
                                                                     const uint32_t* indexReversed,
                                                                     const uint32_t* dimension, uint32_t j, size_t m,
                                                                     uint32_t* x, uint32_t* y) const {
        for (size_t k = 0; k < m; k += 16) {
            const __mmask16 lanes = m - k >= 16 ? __mmask16(0xffff) : __mmask16((1u << (m - k)) - 1u);
            const __m512i s = _mm512_maskz_loadu_epi32(lanes, stream + k);
            const __m512i d = add(_mm512_maskz_loadu_epi32(lanes, dimension + k), j);
            // hashCombine(s, d) = hashU32(s ^ (d + 0x9e3779b9 + (s << 6) + (s >> 2)))
            const __m512i seed = hash(_mm512_xor_si512(
                s, _mm512_add_epi32(_mm512_add_epi32(add(d, 0x9e3779b9u), sll(s, 6)), srl(s, 2))));
            const __m512i i = reverse(laineKarras(_mm512_maskz_loadu_epi32(lanes, indexReversed + k), seed));
            const __m512i px = reverse(laineKarras(i, add(mul(seed, 0x9e3779b9u), 0x632be5abu)));
            const __m512i py = reverse(laineKarras(sobol1(i), add(mul(seed, 0x85ebca6bu), 0x2c1b3c6du)));
            _mm512_mask_storeu_epi32(x + k, lanes, px);
            _mm512_mask_storeu_epi32(y + k, lanes, py);
        }
    }
};

__attribute__((target("avx512f,avx512bw,gfni"))) void next2DGfni(Sampler* const* samplers, size_t n, uint32_t count,
                                                                 glm::vec2* out) {
    drawChunks(samplers, n, count, out, GfniPoints{});
}

// Asked once, at load (a static initialiser may run before libgcc's own CPU detection: initialise it first).
bool cpuHasGfniKernel() {
    __builtin_cpu_init();
    return __builtin_cpu_supports("avx512f") && __builtin_cpu_supports("avx512bw") && __builtin_cpu_supports("gfni");
}
const bool kHasGfni = cpuHasGfniKernel();
#endif

// x86-64: a clone for AVX2 and one for AVX-512 (8 and 16 lanes with a 32-bit multiply; baseline SSE2 has none,
// and its loops are no faster than the calls), chosen at load time by the CPU.
#ifdef NRAD_SAMPLER_GFNI
__attribute__((target_clones("avx512f", "avx2", "default")))
#endif
void next2DPlain(Sampler* const* samplers, size_t n, uint32_t count, glm::vec2* out) {
    drawChunks(samplers, n, count, out, PlainPoints{});
}

}  // namespace

void next2D(Sampler* const* samplers, size_t n, uint32_t count, glm::vec2* out) {
#ifdef NRAD_SAMPLER_GFNI
    if (kHasGfni) return next2DGfni(samplers, n, count, out);
#endif
    next2DPlain(samplers, n, count, out);
}

void next2DWithoutGfni(Sampler* const* samplers, size_t n, uint32_t count, glm::vec2* out) {
    next2DPlain(samplers, n, count, out);
}

}  // namespace nrad
