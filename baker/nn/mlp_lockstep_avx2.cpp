// The lockstep training step with AVX2 and FMA, eight lanes (compiled with -mavx2 -mfma -ffp-contract=off: the same
// bits as the plain lanes of mlp_lockstep.cpp).
#include <immintrin.h>

#define NRAD_LOCKSTEP_KERNELS lockstep_avx2
#include "baker/nn/mlp_lockstep_impl.h"

namespace nrad {
namespace lockstep_avx2 {
namespace {

struct V8 {
    static constexpr int W = 8;
    static constexpr int kGradInputs = 4;
    __m256 v;
    static V8 splat(float x) { return {_mm256_set1_ps(x)}; }
    static V8 load(const float* p) { return {_mm256_loadu_ps(p)}; }
    static void store(float* p, V8 a) { _mm256_storeu_ps(p, a.v); }
    // out[q] = lane j of out[q] = rows[j][q] for q < kPackedFloats: two 8 x 8 transposes.
    static void transposeRows(const float* const rows[W], float* out) {
        for (int half = 0; half < 2; ++half) {
            __m256 r[8], t[8], u[8];
            for (int j = 0; j < 8; ++j) r[j] = _mm256_loadu_ps(rows[j] + 8 * half);
            for (int j = 0; j < 8; j += 2) {
                t[j] = _mm256_unpacklo_ps(r[j], r[j + 1]);
                t[j + 1] = _mm256_unpackhi_ps(r[j], r[j + 1]);
            }
            for (int j = 0; j < 8; j += 4) {
                u[j] = _mm256_shuffle_ps(t[j], t[j + 2], 0x44);
                u[j + 1] = _mm256_shuffle_ps(t[j], t[j + 2], 0xEE);
                u[j + 2] = _mm256_shuffle_ps(t[j + 1], t[j + 3], 0x44);
                u[j + 3] = _mm256_shuffle_ps(t[j + 1], t[j + 3], 0xEE);
            }
            float* o = out + size_t(8 * half) * W;
            for (int q = 0; q < 4; ++q) {
                _mm256_storeu_ps(o + size_t(q) * W, _mm256_permute2f128_ps(u[q], u[q + 4], 0x20));
                _mm256_storeu_ps(o + size_t(q + 4) * W, _mm256_permute2f128_ps(u[q], u[q + 4], 0x31));
            }
        }
    }
};
inline V8 operator+(V8 a, V8 b) { return {_mm256_add_ps(a.v, b.v)}; }
inline V8 operator-(V8 a, V8 b) { return {_mm256_sub_ps(a.v, b.v)}; }
inline V8 operator*(V8 a, V8 b) { return {_mm256_mul_ps(a.v, b.v)}; }
inline V8 operator/(V8 a, V8 b) { return {_mm256_div_ps(a.v, b.v)}; }
inline V8 sqrt(V8 a) { return {_mm256_sqrt_ps(a.v)}; }
inline V8 fma(V8 a, V8 b, V8 c) { return {_mm256_fmadd_ps(a.v, b.v, c.v)}; }
inline V8 whereAboveZero(V8 p, V8 v) { return {_mm256_and_ps(v.v, _mm256_cmp_ps(p.v, _mm256_setzero_ps(), _CMP_GT_OQ))}; }
inline V8 whereLess(V8 a, V8 b, V8 v) { return {_mm256_and_ps(v.v, _mm256_cmp_ps(a.v, b.v, _CMP_LT_OQ))}; }
inline V8 selectAboveZero(V8 m, V8 a, V8 b) { return {_mm256_blendv_ps(b.v, a.v, _mm256_cmp_ps(m.v, _mm256_setzero_ps(), _CMP_GT_OQ))}; }

}  // namespace

void trainStep(LockstepNetworks& nets, const LockstepLane* lanes, LossKind loss, LockstepWorkspace& ws) {
    stepWith<V8>(nets, lanes, loss, ws);
}

}  // namespace lockstep_avx2
}  // namespace nrad
