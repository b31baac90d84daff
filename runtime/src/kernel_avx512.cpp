// AVX-512F kernels: 16 points per vector. Compiled with -mavx512f; called only after the CPU was checked.
// GCC 12's AVX-512 intrinsics pass _mm512_undefined_ps() as the masked-off source, which its
// -Wmaybe-uninitialized / -Wuninitialized report as a use of an uninitialised value (a false positive).
#if defined(__GNUC__) && !defined(__clang__)
#pragma GCC diagnostic ignored "-Wmaybe-uninitialized"
#pragma GCC diagnostic ignored "-Wuninitialized"
#endif
#include <immintrin.h>

#include "kernels.h"

namespace nrad::rt {
namespace {

struct Avx512 {
    using F = __m512;
    using I = __m512i;
    static constexpr int kRegisters = 32;
    static constexpr int W = 16;
    static F load(const float* p) { return _mm512_loadu_ps(p); }
    static void store(float* p, F v) { _mm512_storeu_ps(p, v); }
    static void storei(int32_t* p, I v) { _mm512_storeu_si512(p, v); }
    static F set1(float x) { return _mm512_set1_ps(x); }
    static I seti(int x) { return _mm512_set1_epi32(x); }
    static F zero() { return _mm512_setzero_ps(); }
    static F add(F a, F b) { return _mm512_add_ps(a, b); }
    static F sub(F a, F b) { return _mm512_sub_ps(a, b); }
    static F mul(F a, F b) { return _mm512_mul_ps(a, b); }
    static F div(F a, F b) { return _mm512_div_ps(a, b); }
    // Lanes whose bit is set in mask from a, the others from b.
    static F select(unsigned mask, F a, F b) { return _mm512_mask_blend_ps(__mmask16(mask), b, a); }
    static F fmadd(F a, F b, F c) { return _mm512_fmadd_ps(a, b, c); }
    static F fnmadd(F a, F b, F c) { return _mm512_fnmadd_ps(a, b, c); }
    static F min(F a, F b) { return _mm512_min_ps(a, b); }
    static F max(F a, F b) { return _mm512_max_ps(a, b); }
    static F roundNearest(F a) { return _mm512_roundscale_ps(a, _MM_FROUND_TO_NEAREST_INT | _MM_FROUND_NO_EXC); }
    static I cvtTrunc(F a) { return _mm512_cvttps_epi32(a); }
    static F cvtFloat(I a) { return _mm512_cvtepi32_ps(a); }
    static I addi(I a, I b) { return _mm512_add_epi32(a, b); }
    static I mullo(I a, I b) { return _mm512_mullo_epi32(a, b); }
    static I mini(I a, I b) { return _mm512_min_epi32(a, b); }
    static I selecti(unsigned mask, I a, I b) { return _mm512_mask_blend_epi32(__mmask16(mask), b, a); }
    static I gatheri(const int32_t* base, I index) { return _mm512_i32gather_epi32(index, base, 4); }
    static F gatherf(const float* base, I index) { return _mm512_i32gather_ps(index, base, 4); }
    static unsigned geMask(F a, F b) { return _mm512_cmp_ps_mask(a, b, _CMP_GE_OQ); }
    static unsigned leMask(F a, F b) { return _mm512_cmp_ps_mask(a, b, _CMP_LE_OQ); }
    static int32_t firstLane(I a) { return _mm_cvtsi128_si32(_mm512_castsi512_si128(a)); }
    static unsigned equalMask(I a, I b) { return _mm512_cmpeq_epi32_mask(a, b); }
    static unsigned equalMask(F a, F b) { return _mm512_cmp_ps_mask(a, b, _CMP_EQ_OQ); }
    static F timesPow2(F q, F n) { return _mm512_scalef_ps(q, n); }
    static void deinterleave3(F a, F b, F c, F out[3]);
    static void interleave3(const F in[3], F out[3]);
    static F sqrt(F a) { return _mm512_sqrt_ps(a); }
    static F loadHalf(const uint16_t* p) { return _mm512_cvtph_ps(_mm256_loadu_si256(reinterpret_cast<const __m256i*>(p))); }
    static void storeHalf(uint16_t* p, F v) {  // floatToHalfF16c's rule
        _mm256_storeu_si256(reinterpret_cast<__m256i*>(p),
                            _mm512_cvtps_ph(_mm512_min_ps(v, _mm512_set1_ps(65504.0f)), _MM_FROUND_TO_NEAREST_INT | _MM_FROUND_NO_EXC));
    }
    static constexpr bool kStridedLoads = false;  // G-buffers through simd_impl.h's exact per-point reads
    static constexpr bool kHalfRgbaStore = false;
    static constexpr bool kSurfaceLoads = false;
};

}  // namespace

namespace {
#include "simd_impl.h"

using Lanes = Interleave<16>;
constexpr Lanes::Tables kTables = Lanes::tables();

template <int S, int C>
__m512 blendFrom(__m512 into, __m512 v) {
    return _mm512_mask_blend_ps(__mmask16(Lanes::kMask<S, C>), into, v);
}

void Avx512::deinterleave3(F a, F b, F c, F out[3]) {
    out[0] = _mm512_permutexvar_ps(_mm512_loadu_si512(kTables.gather[0]), blendFrom<2, 0>(blendFrom<1, 0>(a, b), c));
    out[1] = _mm512_permutexvar_ps(_mm512_loadu_si512(kTables.gather[1]), blendFrom<2, 1>(blendFrom<1, 1>(a, b), c));
    out[2] = _mm512_permutexvar_ps(_mm512_loadu_si512(kTables.gather[2]), blendFrom<2, 2>(blendFrom<1, 2>(a, b), c));
}

void Avx512::interleave3(const F in[3], F out[3]) {
    F q[3];
    for (int k = 0; k < 3; ++k) q[k] = _mm512_permutexvar_ps(_mm512_loadu_si512(kTables.scatter[k]), in[k]);
    out[0] = blendFrom<0, 2>(blendFrom<0, 1>(q[0], q[1]), q[2]);
    out[1] = blendFrom<1, 2>(blendFrom<1, 1>(q[0], q[1]), q[2]);
    out[2] = blendFrom<2, 2>(blendFrom<2, 1>(q[0], q[1]), q[2]);
}
}  // namespace

void evalChunkAvx512(const NetworkView& net, const float* x, float* y, int count) { evalChunk<Avx512>(net, x, y, count); }

void evalBlocksAvx512(const BlockContext& ctx, size_t blocks, Deferred& def) {
    if (ctx.io.stride == 1)
        evalBlocks<Avx512, 1>(ctx, blocks, def);
    else
        evalBlocks<Avx512, 3>(ctx, blocks, def);
}

}  // namespace nrad::rt
