// NEON kernels for 64-bit ARM: 4 points per vector, the vector traits of simd_impl.h on AArch64's Advanced
// SIMD (mandatory in ARMv8-A: no run-time check needed). min/max follow the x86 rule simd_impl.h relies on
// (the second operand when either is NaN), not NEON's own (NaN); interleaved xyz is NEON's vld3/vst3.
#include <arm_neon.h>

#include "kernels.h"

namespace nrad::rt {
namespace {

struct Neon {
    using F = float32x4_t;
    using I = int32x4_t;
    static constexpr int kRegisters = 32;
    static constexpr int W = 4;
    static F load(const float* p) { return vld1q_f32(p); }
    static void store(float* p, F v) { vst1q_f32(p, v); }
    static void storei(int32_t* p, I v) { vst1q_s32(p, v); }
    static F set1(float x) { return vdupq_n_f32(x); }
    static I seti(int x) { return vdupq_n_s32(x); }
    static F zero() { return vdupq_n_f32(0.0f); }
    static F add(F a, F b) { return vaddq_f32(a, b); }
    static F sub(F a, F b) { return vsubq_f32(a, b); }
    static F mul(F a, F b) { return vmulq_f32(a, b); }
    static F div(F a, F b) { return vdivq_f32(a, b); }
    static uint32x4_t bits() {
        static const uint32_t b[4] = {1, 2, 4, 8};
        return vld1q_u32(b);
    }
    static unsigned toMask(uint32x4_t m) { return vaddvq_u32(vandq_u32(m, bits())); }
    // Lanes whose bit is set in mask from a, the others from b.
    static F select(unsigned mask, F a, F b) { return vbslq_f32(vtstq_u32(vdupq_n_u32(mask), bits()), a, b); }
    static F fmadd(F a, F b, F c) { return vfmaq_f32(c, a, b); }
    static F fnmadd(F a, F b, F c) { return vfmsq_f32(c, a, b); }
    static F min(F a, F b) { return vbslq_f32(vcltq_f32(a, b), a, b); }  // a < b ? a : b, as minps
    static F max(F a, F b) { return vbslq_f32(vcgtq_f32(a, b), a, b); }  // a > b ? a : b, as maxps
    static F roundNearest(F a) { return vrndnq_f32(a); }
    static I cvtTrunc(F a) { return vcvtq_s32_f32(a); }
    static F cvtFloat(I a) { return vcvtq_f32_s32(a); }
    static I addi(I a, I b) { return vaddq_s32(a, b); }
    static I mullo(I a, I b) { return vmulq_s32(a, b); }
    static I mini(I a, I b) { return vminq_s32(a, b); }
    static I selecti(unsigned mask, I a, I b) { return vbslq_s32(vtstq_u32(vdupq_n_u32(mask), bits()), a, b); }
    static I gatheri(const int32_t* base, I index) {  // no gather instruction: lane by lane
        int32_t at[4], v[4];
        vst1q_s32(at, index);
        for (int l = 0; l < 4; ++l) v[l] = base[at[l]];
        return vld1q_s32(v);
    }
    static F gatherf(const float* base, I index) {
        int32_t at[4];
        float v[4];
        vst1q_s32(at, index);
        for (int l = 0; l < 4; ++l) v[l] = base[at[l]];
        return vld1q_f32(v);
    }
    static unsigned geMask(F a, F b) { return toMask(vcgeq_f32(a, b)); }
    static unsigned leMask(F a, F b) { return toMask(vcleq_f32(a, b)); }
    static int32_t firstLane(I a) { return vgetq_lane_s32(a, 0); }
    static unsigned equalMask(I a, I b) { return toMask(vceqq_s32(a, b)); }
    static unsigned equalMask(F a, F b) { return toMask(vceqq_f32(a, b)); }
    // q 2^n by building 2^n's exponent bits.
    static F timesPow2(F q, F n) {
        return vmulq_f32(q, vreinterpretq_f32_s32(vshlq_n_s32(vaddq_s32(vcvtnq_s32_f32(n), vdupq_n_s32(127)), 23)));
    }
    static void deinterleave3(F a, F b, F c, F out[3]) {
        float xyz[12];
        vst1q_f32(xyz, a);
        vst1q_f32(xyz + 4, b);
        vst1q_f32(xyz + 8, c);
        const float32x4x3_t v = vld3q_f32(xyz);
        out[0] = v.val[0];
        out[1] = v.val[1];
        out[2] = v.val[2];
    }
    static void interleave3(const F in[3], F out[3]) {
        float xyz[12];
        float32x4x3_t v;
        v.val[0] = in[0];
        v.val[1] = in[1];
        v.val[2] = in[2];
        vst3q_f32(xyz, v);
        out[0] = vld1q_f32(xyz);
        out[1] = vld1q_f32(xyz + 4);
        out[2] = vld1q_f32(xyz + 8);
    }
    static F sqrt(F a) { return vsqrtq_f32(a); }
    static F loadHalf(const uint16_t* p) { return vcvt_f32_f16(vreinterpret_f16_u16(vld1_u16(p))); }
    static void storeHalf(uint16_t* p, F v) {  // floatToHalfNeon's rule (v is never NaN)
        vst1_u16(p, vreinterpret_u16_f16(vcvt_f16_f32(vminq_f32(v, vdupq_n_f32(65504.0f)))));
    }
    static constexpr bool kStridedLoads = false;  // G-buffers through simd_impl.h's exact per-point reads
    static constexpr bool kRgbaStores = false;
    static constexpr bool kSurfaceLoads = false;
};

#include "simd_impl.h"

float halfToFloatOne(uint16_t h) { return vgetq_lane_f32(vcvt_f32_f16(vreinterpret_f16_u16(vdup_n_u16(h))), 0); }
uint16_t floatToHalfOne(float f) { return vget_lane_u16(vreinterpret_u16_f16(vcvt_f16_f32(vdupq_n_f32(f))), 0); }

}  // namespace

void evalChunkNeon(const NetworkView& net, const float* x, float* y, int count) { evalChunk<Neon>(net, x, y, count); }

void halfToFloatNeon(const uint16_t* in, float* out, size_t n) {
    size_t i = 0;
    for (; i + 4 <= n; i += 4) vst1q_f32(out + i, vcvt_f32_f16(vreinterpret_f16_u16(vld1_u16(in + i))));
    for (; i < n; ++i) out[i] = halfToFloatOne(in[i]);
}

void floatToHalfNeon(const float* in, uint16_t* out, size_t n) {
    // Saturate at 65504 first (format::floatToHalf's rule); the conversion rounds to nearest even.
    const float32x4_t top = vdupq_n_f32(65504.0f);
    size_t i = 0;
    for (; i + 4 <= n; i += 4) vst1_u16(out + i, vreinterpret_u16_f16(vcvt_f16_f32(vminq_f32(vld1q_f32(in + i), top))));
    for (; i < n; ++i) out[i] = floatToHalfOne(in[i] < 65504.0f ? in[i] : 65504.0f);
}

void evalBlocksNeon(const BlockContext& ctx, size_t blocks, Deferred& def) {
    if (ctx.io.stride == 1)
        evalBlocks<Neon, 1>(ctx, blocks, def);
    else
        evalBlocks<Neon, 3>(ctx, blocks, def);
}

}  // namespace nrad::rt
