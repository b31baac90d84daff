// The lockstep training step with NEON (AArch64), eight lanes as two 128-bit registers (compiled with
// -ffp-contract=off: vfmaq_f32 is the only fusion, as std::fma in the plain lanes; vdivq_f32 and vsqrtq_f32 are
// correctly rounded, so the bits are the plain lanes' of mlp_lockstep.cpp).
#include <arm_neon.h>

#define NRAD_LOCKSTEP_KERNELS lockstep_neon
#include "baker/nn/mlp_lockstep_impl.h"

namespace nrad {
namespace lockstep_neon {
namespace {

struct V8 {
    static constexpr int W = 8;
    static constexpr int kGradInputs = 4;
    float32x4_t lo, hi;
    static V8 splat(float x) { return {vdupq_n_f32(x), vdupq_n_f32(x)}; }
    static V8 load(const float* p) { return {vld1q_f32(p), vld1q_f32(p + 4)}; }
    static void store(float* p, V8 a) {
        vst1q_f32(p, a.lo);
        vst1q_f32(p + 4, a.hi);
    }
    // out[q W + j] = rows[j][q]: 4 x 4 transposes of each four rows' four columns.
    static void transposeRows(const float* const rows[W], float* out) {
        for (int h = 0; h < 2; ++h)  // rows 4 h .. 4 h + 3, lanes 4 h .. 4 h + 3 of every column
            for (int c = 0; c < kPackedFloats; c += 4) {
                const float32x4x2_t a = vtrnq_f32(vld1q_f32(rows[4 * h] + c), vld1q_f32(rows[4 * h + 1] + c));
                const float32x4x2_t b = vtrnq_f32(vld1q_f32(rows[4 * h + 2] + c), vld1q_f32(rows[4 * h + 3] + c));
                float* o = out + size_t(c) * W + size_t(4 * h);
                vst1q_f32(o, vcombine_f32(vget_low_f32(a.val[0]), vget_low_f32(b.val[0])));
                vst1q_f32(o + W, vcombine_f32(vget_low_f32(a.val[1]), vget_low_f32(b.val[1])));
                vst1q_f32(o + 2 * W, vcombine_f32(vget_high_f32(a.val[0]), vget_high_f32(b.val[0])));
                vst1q_f32(o + 3 * W, vcombine_f32(vget_high_f32(a.val[1]), vget_high_f32(b.val[1])));
            }
    }
};
inline V8 operator+(V8 a, V8 b) { return {vaddq_f32(a.lo, b.lo), vaddq_f32(a.hi, b.hi)}; }
inline V8 operator-(V8 a, V8 b) { return {vsubq_f32(a.lo, b.lo), vsubq_f32(a.hi, b.hi)}; }
inline V8 operator*(V8 a, V8 b) { return {vmulq_f32(a.lo, b.lo), vmulq_f32(a.hi, b.hi)}; }
inline V8 operator/(V8 a, V8 b) { return {vdivq_f32(a.lo, b.lo), vdivq_f32(a.hi, b.hi)}; }
inline V8 sqrt(V8 a) { return {vsqrtq_f32(a.lo), vsqrtq_f32(a.hi)}; }
inline V8 fma(V8 a, V8 b, V8 c) { return {vfmaq_f32(c.lo, a.lo, b.lo), vfmaq_f32(c.hi, a.hi, b.hi)}; }  // c + a b, one rounding
inline float32x4_t keep(uint32x4_t mask, float32x4_t v) {
    return vreinterpretq_f32_u32(vandq_u32(mask, vreinterpretq_u32_f32(v)));
}
inline V8 whereAboveZero(V8 p, V8 v) {
    const float32x4_t z = vdupq_n_f32(0.0f);
    return {keep(vcgtq_f32(p.lo, z), v.lo), keep(vcgtq_f32(p.hi, z), v.hi)};
}
inline V8 whereLess(V8 a, V8 b, V8 v) { return {keep(vcltq_f32(a.lo, b.lo), v.lo), keep(vcltq_f32(a.hi, b.hi), v.hi)}; }
inline V8 selectAboveZero(V8 m, V8 a, V8 b) {
    const float32x4_t z = vdupq_n_f32(0.0f);
    return {vbslq_f32(vcgtq_f32(m.lo, z), a.lo, b.lo), vbslq_f32(vcgtq_f32(m.hi, z), a.hi, b.hi)};
}

}  // namespace

void trainStep(LockstepNetworks& nets, const LockstepLane* lanes, LossKind loss, LockstepWorkspace& ws) {
    stepWith<V8>(nets, lanes, loss, ws);
}

}  // namespace lockstep_neon
}  // namespace nrad
