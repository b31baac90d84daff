// The lockstep training step with AVX-512F, sixteen lanes (compiled with -mavx512f -ffp-contract=off: the same bits
// as the plain lanes of mlp_lockstep.cpp). Chosen where the CPU has AVX-512F (mlp_lockstep.cpp).
// GCC 12's AVX-512 intrinsics pass _mm512_undefined_ps() as the masked-off source, which its
// -Wmaybe-uninitialized reports as a use of an uninitialised value (a false positive; runtime/src/kernel_avx512.cpp).
#if defined(__GNUC__) && !defined(__clang__)
#pragma GCC diagnostic ignored "-Wmaybe-uninitialized"
#pragma GCC diagnostic ignored "-Wuninitialized"
#endif
#include <immintrin.h>

#define NRAD_LOCKSTEP_KERNELS lockstep_avx512
#include "baker/nn/mlp_lockstep_impl.h"

namespace nrad {
namespace lockstep_avx512 {
namespace {

struct V16 {
    static constexpr int W = 16;
    static constexpr int kGradInputs = 8;
    __m512 v;
    static V16 splat(float x) { return {_mm512_set1_ps(x)}; }
    static V16 load(const float* p) { return {_mm512_loadu_ps(p)}; }
    static void store(float* p, V16 a) { _mm512_storeu_ps(p, a.v); }
    // out[q] = lane j of out[q] = rows[j][q] for q < kPackedFloats (16): a 16 x 16 transpose. After the unpacks and
    // 32-bit shuffles, 128-bit lane L of u[4 i + c] holds column 4 L + c of rows 4 i .. 4 i + 3; two rounds of
    // 128-bit shuffles gather lane L of u[c], u[4 + c], u[8 + c], u[12 + c].
    static void transposeRows(const float* const rows[W], float* out) {
        __m512 r[16], t[16], u[16];
        for (int j = 0; j < 16; ++j) r[j] = _mm512_loadu_ps(rows[j]);
        for (int j = 0; j < 16; j += 2) {
            t[j] = _mm512_unpacklo_ps(r[j], r[j + 1]);
            t[j + 1] = _mm512_unpackhi_ps(r[j], r[j + 1]);
        }
        for (int j = 0; j < 16; j += 4) {
            u[j] = _mm512_shuffle_ps(t[j], t[j + 2], 0x44);
            u[j + 1] = _mm512_shuffle_ps(t[j], t[j + 2], 0xEE);
            u[j + 2] = _mm512_shuffle_ps(t[j + 1], t[j + 3], 0x44);
            u[j + 3] = _mm512_shuffle_ps(t[j + 1], t[j + 3], 0xEE);
        }
        for (int c = 0; c < 4; ++c) {
            const __m512 a0 = _mm512_shuffle_f32x4(u[c], u[4 + c], _MM_SHUFFLE(2, 0, 2, 0));  // L0 L2 of u[c], of u[4 + c]
            const __m512 a1 = _mm512_shuffle_f32x4(u[c], u[4 + c], _MM_SHUFFLE(3, 1, 3, 1));  // L1 L3
            const __m512 b0 = _mm512_shuffle_f32x4(u[8 + c], u[12 + c], _MM_SHUFFLE(2, 0, 2, 0));
            const __m512 b1 = _mm512_shuffle_f32x4(u[8 + c], u[12 + c], _MM_SHUFFLE(3, 1, 3, 1));
            _mm512_storeu_ps(out + size_t(c) * W, _mm512_shuffle_f32x4(a0, b0, _MM_SHUFFLE(2, 0, 2, 0)));  // L = 0
            _mm512_storeu_ps(out + size_t(4 + c) * W, _mm512_shuffle_f32x4(a1, b1, _MM_SHUFFLE(2, 0, 2, 0)));  // L = 1
            _mm512_storeu_ps(out + size_t(8 + c) * W, _mm512_shuffle_f32x4(a0, b0, _MM_SHUFFLE(3, 1, 3, 1)));  // L = 2
            _mm512_storeu_ps(out + size_t(12 + c) * W, _mm512_shuffle_f32x4(a1, b1, _MM_SHUFFLE(3, 1, 3, 1)));  // L = 3
        }
    }
};
inline V16 operator+(V16 a, V16 b) { return {_mm512_add_ps(a.v, b.v)}; }
inline V16 operator-(V16 a, V16 b) { return {_mm512_sub_ps(a.v, b.v)}; }
inline V16 operator*(V16 a, V16 b) { return {_mm512_mul_ps(a.v, b.v)}; }
inline V16 operator/(V16 a, V16 b) { return {_mm512_div_ps(a.v, b.v)}; }
inline V16 sqrt(V16 a) { return {_mm512_sqrt_ps(a.v)}; }
inline V16 fma(V16 a, V16 b, V16 c) { return {_mm512_fmadd_ps(a.v, b.v, c.v)}; }
inline V16 whereAboveZero(V16 p, V16 v) {
    return {_mm512_maskz_mov_ps(_mm512_cmp_ps_mask(p.v, _mm512_setzero_ps(), _CMP_GT_OQ), v.v)};
}
inline V16 whereLess(V16 a, V16 b, V16 v) { return {_mm512_maskz_mov_ps(_mm512_cmp_ps_mask(a.v, b.v, _CMP_LT_OQ), v.v)}; }
inline V16 selectAboveZero(V16 m, V16 a, V16 b) {
    return {_mm512_mask_blend_ps(_mm512_cmp_ps_mask(m.v, _mm512_setzero_ps(), _CMP_GT_OQ), b.v, a.v)};
}

}  // namespace

void trainStep(LockstepNetworks& nets, const LockstepLane* lanes, LossKind loss, LockstepWorkspace& ws) {
    stepWith<V16>(nets, lanes, loss, ws);
}

}  // namespace lockstep_avx512
}  // namespace nrad
