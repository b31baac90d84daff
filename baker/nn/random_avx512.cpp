// drawBelowDescending and remaindersDescending (random.h) eight at a time with AVX-512F and DQ (compiled with
// -mavx512f -mavx512dq -ffp-contract=off; chosen where the CPU has both): SplitMix64's outputs lane by lane, and the
// remainders exact as the scalar path's in random.cpp, so the same bits.
#if defined(__GNUC__) && !defined(__clang__)
#pragma GCC diagnostic ignored "-Wmaybe-uninitialized"  // GCC 12's intrinsics (mlp_lockstep_avx512.cpp)
#pragma GCC diagnostic ignored "-Wuninitialized"
#endif
#include <immintrin.h>

#include "baker/nn/random.h"

namespace nrad {

namespace {

inline __m512d remainderStep(__m512d v, __m512d n, __m512d inverse) {
    const __m512d q = _mm512_roundscale_pd(_mm512_mul_pd(v, inverse), _MM_FROUND_TO_NEG_INF | _MM_FROUND_NO_EXC);
    __m512d r = _mm512_fnmadd_pd(q, n, v);
    r = _mm512_mask_add_pd(r, _mm512_cmp_pd_mask(r, _mm512_setzero_pd(), _CMP_LT_OQ), r, n);
    r = _mm512_mask_sub_pd(r, _mm512_cmp_pd_mask(r, n, _CMP_GE_OQ), r, n);
    return r;
}

// The remainders of lanes z by n (one step per digit, as remaindersDescendingScalar).
inline __m512d remainders(__m512i z, __m512d n) {
    const __m512i mask21 = _mm512_set1_epi64(0x1fffff);
    // 1 / n to 14 bits, one Newton step to about 28: a quotient below 2^22 off by under 1 / 32, so by at most one after
    // the floor, which remainderStep corrects.
    const __m512d e0 = _mm512_rcp14_pd(n);
    const __m512d inverse = _mm512_mul_pd(e0, _mm512_fnmadd_pd(n, e0, _mm512_set1_pd(2.0)));
    const __m512d twoTo21 = _mm512_set1_pd(0x1p21);
    __m512d r = remainderStep(_mm512_cvtepu64_pd(_mm512_srli_epi64(z, 42)), n, inverse);
    r = remainderStep(_mm512_fmadd_pd(r, twoTo21, _mm512_cvtepu64_pd(_mm512_and_si512(_mm512_srli_epi64(z, 21), mask21))), n, inverse);
    return remainderStep(_mm512_fmadd_pd(r, twoTo21, _mm512_cvtepu64_pd(_mm512_and_si512(z, mask21))), n, inverse);
}

inline void store32(uint32_t* out, __m512d r) {
    _mm256_storeu_si256(reinterpret_cast<__m256i*>(out), _mm512_cvtepi64_epi32(_mm512_cvttpd_epu64(r)));
}

}  // namespace

void drawBelowDescendingAvx512(SplitMix64& rng, uint64_t top, uint32_t count, uint32_t* out) {
    const __m512i lane = _mm512_set_epi64(7, 6, 5, 4, 3, 2, 1, 0);
    const __m512i c1 = _mm512_set1_epi64(int64_t(0xbf58476d1ce4e5b9ull)), c2 = _mm512_set1_epi64(int64_t(0x94d049bb133111ebull));
    // Lane j's state steps: (j + 1) increments, then eight per vector.
    const __m512i first = _mm512_mullo_epi64(_mm512_add_epi64(lane, _mm512_set1_epi64(1)), _mm512_set1_epi64(int64_t(SplitMix64::kIncrement)));
    const __m512i step = _mm512_set1_epi64(int64_t(8 * SplitMix64::kIncrement));
    const uint32_t vectors = count / 8;
    __m512i state = _mm512_add_epi64(_mm512_set1_epi64(int64_t(rng.skip(uint64_t(vectors) * 8))), first);
    __m512i n = _mm512_sub_epi64(_mm512_set1_epi64(int64_t(top)), lane);  // top - k - j
    const __m512i eight = _mm512_set1_epi64(8);
    for (uint32_t v = 0; v < vectors; ++v) {
        __m512i z = state;
        z = _mm512_mullo_epi64(_mm512_xor_si512(z, _mm512_srli_epi64(z, 30)), c1);
        z = _mm512_mullo_epi64(_mm512_xor_si512(z, _mm512_srli_epi64(z, 27)), c2);
        z = _mm512_xor_si512(z, _mm512_srli_epi64(z, 31));
        store32(out + 8 * v, remainders(z, _mm512_cvtepu64_pd(n)));
        state = _mm512_add_epi64(state, step);
        n = _mm512_sub_epi64(n, eight);
    }
    const uint32_t k = vectors * 8;
    if (k < count) {
        uint64_t x[8];
        for (uint32_t j = 0; j < count - k; ++j) x[j] = rng.next();
        remaindersDescendingScalar(x, top - k, count - k, out + k);
    }
}

void remaindersDescendingAvx512(const uint64_t* x, uint64_t top, uint32_t count, uint32_t* out) {
    const __m512i lane = _mm512_set_epi64(7, 6, 5, 4, 3, 2, 1, 0);
    uint32_t k = 0;
    for (; k + 8 <= count; k += 8)
        store32(out + k, remainders(_mm512_loadu_si512(x + k), _mm512_cvtepu64_pd(_mm512_sub_epi64(_mm512_set1_epi64(int64_t(top - k)), lane))));
    if (k < count) remaindersDescendingScalar(x + k, top - k, count - k, out + k);
}

}  // namespace nrad
