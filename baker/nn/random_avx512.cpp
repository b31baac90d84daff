// remaindersDescending (random.h) eight at a time with AVX-512F and DQ (compiled with -mavx512f -mavx512dq
// -ffp-contract=off; chosen where the CPU has both): the same digits, quotients and corrections as the scalar path
// in random.cpp, lane by lane, so the same bits.
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

}  // namespace

void remaindersDescendingAvx512(const uint64_t* x, uint64_t top, uint32_t count, uint32_t* out) {
    const __m512i lane = _mm512_set_epi64(7, 6, 5, 4, 3, 2, 1, 0), mask21 = _mm512_set1_epi64(0x1fffff);
    const __m512d twoTo21 = _mm512_set1_pd(0x1p21), one = _mm512_set1_pd(1.0);
    uint32_t k = 0;
    for (; k + 8 <= count; k += 8) {
        const __m512i z = _mm512_loadu_si512(x + k);
        const __m512d n = _mm512_cvtepu64_pd(_mm512_sub_epi64(_mm512_set1_epi64(int64_t(top - k)), lane));  // top - k - j
        const __m512d inverse = _mm512_div_pd(one, n);
        __m512d r = remainderStep(_mm512_cvtepu64_pd(_mm512_srli_epi64(z, 42)), n, inverse);
        r = remainderStep(_mm512_fmadd_pd(r, twoTo21, _mm512_cvtepu64_pd(_mm512_and_si512(_mm512_srli_epi64(z, 21), mask21))), n, inverse);
        r = remainderStep(_mm512_fmadd_pd(r, twoTo21, _mm512_cvtepu64_pd(_mm512_and_si512(z, mask21))), n, inverse);
        _mm256_storeu_si256(reinterpret_cast<__m256i*>(out + k), _mm512_cvtepi64_epi32(_mm512_cvttpd_epu64(r)));
    }
    if (k < count) remaindersDescendingScalar(x + k, top - k, count - k, out + k);
}

}  // namespace nrad
