// AVX2 + FMA kernels: 8 points per vector, and F16C's fp16 conversions. Compiled with -mavx2 -mfma -mf16c;
// called only after the CPU was checked.
#include <immintrin.h>

#include "kernels.h"

namespace nrad::rt {
namespace {

struct Avx2 {
    using F = __m256;
    using I = __m256i;
    static constexpr int kRegisters = 16;
    static constexpr int W = 8;
    static F load(const float* p) { return _mm256_loadu_ps(p); }
    static void store(float* p, F v) { _mm256_storeu_ps(p, v); }
    static void storei(int32_t* p, I v) { _mm256_storeu_si256(reinterpret_cast<__m256i*>(p), v); }
    static F set1(float x) { return _mm256_set1_ps(x); }
    static I seti(int x) { return _mm256_set1_epi32(x); }
    static F zero() { return _mm256_setzero_ps(); }
    static F add(F a, F b) { return _mm256_add_ps(a, b); }
    static F sub(F a, F b) { return _mm256_sub_ps(a, b); }
    static F mul(F a, F b) { return _mm256_mul_ps(a, b); }
    static F div(F a, F b) { return _mm256_div_ps(a, b); }
    // Lanes whose bit is set in mask from a, the others from b.
    static F select(unsigned mask, F a, F b) {
        const __m256i bit = _mm256_setr_epi32(1, 2, 4, 8, 16, 32, 64, 128);
        const __m256i on = _mm256_cmpeq_epi32(_mm256_and_si256(_mm256_set1_epi32(int(mask)), bit), bit);
        return _mm256_blendv_ps(b, a, _mm256_castsi256_ps(on));
    }
    static F fmadd(F a, F b, F c) { return _mm256_fmadd_ps(a, b, c); }
    static F fnmadd(F a, F b, F c) { return _mm256_fnmadd_ps(a, b, c); }
    static F min(F a, F b) { return _mm256_min_ps(a, b); }
    static F max(F a, F b) { return _mm256_max_ps(a, b); }
    static F roundNearest(F a) { return _mm256_round_ps(a, _MM_FROUND_TO_NEAREST_INT | _MM_FROUND_NO_EXC); }
    static I cvtTrunc(F a) { return _mm256_cvttps_epi32(a); }
    static F cvtFloat(I a) { return _mm256_cvtepi32_ps(a); }
    static I addi(I a, I b) { return _mm256_add_epi32(a, b); }
    static I mullo(I a, I b) { return _mm256_mullo_epi32(a, b); }
    static I mini(I a, I b) { return _mm256_min_epi32(a, b); }
    // Lanes whose bit is set in mask from a, the others from b.
    static I selecti(unsigned mask, I a, I b) { return _mm256_castps_si256(select(mask, _mm256_castsi256_ps(a), _mm256_castsi256_ps(b))); }
    static I gatheri(const int32_t* base, I index) { return _mm256_i32gather_epi32(base, index, 4); }
    static F gatherf(const float* base, I index) { return _mm256_i32gather_ps(base, index, 4); }
    static unsigned geMask(F a, F b) { return unsigned(_mm256_movemask_ps(_mm256_cmp_ps(a, b, _CMP_GE_OQ))); }
    static unsigned leMask(F a, F b) { return unsigned(_mm256_movemask_ps(_mm256_cmp_ps(a, b, _CMP_LE_OQ))); }
    static int32_t firstLane(I a) { return _mm_cvtsi128_si32(_mm256_castsi256_si128(a)); }
    static unsigned equalMask(I a, I b) { return unsigned(_mm256_movemask_ps(_mm256_castsi256_ps(_mm256_cmpeq_epi32(a, b)))); }
    static unsigned equalMask(F a, F b) { return unsigned(_mm256_movemask_ps(_mm256_cmp_ps(a, b, _CMP_EQ_OQ))); }
    // q 2^n by building 2^n's exponent bits.
    static F timesPow2(F q, F n) {
        return _mm256_mul_ps(q, _mm256_castsi256_ps(_mm256_slli_epi32(_mm256_add_epi32(_mm256_cvtps_epi32(n), _mm256_set1_epi32(127)), 23)));
    }
    static void deinterleave3(F a, F b, F c, F out[3]);
    static void interleave3(const F in[3], F out[3]);
    static F sqrt(F a) { return _mm256_sqrt_ps(a); }
    static F loadHalf(const uint16_t* p) { return _mm256_cvtph_ps(_mm_loadu_si128(reinterpret_cast<const __m128i*>(p))); }
    static __m128i toHalf(F v) {  // floatToHalfF16c's rule
        return _mm256_cvtps_ph(_mm256_min_ps(v, _mm256_set1_ps(65504.0f)), _MM_FROUND_TO_NEAREST_INT | _MM_FROUND_NO_EXC);
    }
    static void storeHalf(uint16_t* p, F v) { _mm_storeu_si128(reinterpret_cast<__m128i*>(p), toHalf(v)); }

    // Eight points' x y z (and the next 4 bytes) as rows, transposed: 16-byte loads, two points per 256-bit row.
    static constexpr bool kStridedLoads = true;
    static void loadStrided3(const uint8_t* s, size_t stride, F v[3]) {
        auto row = [&](int l) {
            return _mm256_insertf128_ps(_mm256_castps128_ps256(_mm_loadu_ps(reinterpret_cast<const float*>(s + size_t(l) * stride))),
                                        _mm_loadu_ps(reinterpret_cast<const float*>(s + size_t(l + 4) * stride)), 1);
        };
        const F r0 = row(0), r1 = row(1), r2 = row(2), r3 = row(3);  // [point l | point l + 4]
        const F t0 = _mm256_unpacklo_ps(r0, r1), t1 = _mm256_unpackhi_ps(r0, r1);  // x0 x1 y0 y1 | x4 x5 y4 y5, z...
        const F t2 = _mm256_unpacklo_ps(r2, r3), t3 = _mm256_unpackhi_ps(r2, r3);
        v[0] = _mm256_shuffle_ps(t0, t2, _MM_SHUFFLE(1, 0, 1, 0));
        v[1] = _mm256_shuffle_ps(t0, t2, _MM_SHUFFLE(3, 2, 3, 2));
        v[2] = _mm256_shuffle_ps(t1, t3, _MM_SHUFFLE(1, 0, 1, 0));
    }
    // Eight points' x y z (and the next 2 bytes) in fp16: 8-byte loads, a 16-bit transpose, F16C.
    static void loadStrided3Half(const uint8_t* s, size_t stride, F v[3]) {
        __m128i q[8];
        for (int l = 0; l < 8; ++l) q[l] = _mm_loadl_epi64(reinterpret_cast<const __m128i*>(s + size_t(l) * stride));
        const __m128i a0 = _mm_unpacklo_epi16(q[0], q[1]), a1 = _mm_unpacklo_epi16(q[2], q[3]);  // x0 x1 y0 y1 z0 z1 . .
        const __m128i a2 = _mm_unpacklo_epi16(q[4], q[5]), a3 = _mm_unpacklo_epi16(q[6], q[7]);
        const __m128i b0 = _mm_unpacklo_epi32(a0, a1), b1 = _mm_unpackhi_epi32(a0, a1);  // x0..x3 y0..y3, z0..z3 . .
        const __m128i b2 = _mm_unpacklo_epi32(a2, a3), b3 = _mm_unpackhi_epi32(a2, a3);
        v[0] = _mm256_cvtph_ps(_mm_unpacklo_epi64(b0, b2));
        v[1] = _mm256_cvtph_ps(_mm_unpackhi_epi64(b0, b2));
        v[2] = _mm256_cvtph_ps(_mm_unpacklo_epi64(b1, b3));
    }
    // Eight NradSurfaces' nine floats: the first eight of each (32 bytes, inside the surface) as rows of an 8 x 8
    // transpose, the ninth copied.
    static constexpr bool kSurfaceLoads = true;
    static void loadSurfaces(const uint8_t* s, size_t stride, F m[9]) {
        F r[8];
        alignas(32) float ninth[8];
        for (int l = 0; l < 8; ++l) {
            r[l] = _mm256_loadu_ps(reinterpret_cast<const float*>(s + size_t(l) * stride));
            std::memcpy(&ninth[l], s + size_t(l) * stride + 32, 4);
        }
        F t[8], u[8];
        for (int k = 0; k < 4; ++k) {
            t[2 * k] = _mm256_unpacklo_ps(r[2 * k], r[2 * k + 1]);
            t[2 * k + 1] = _mm256_unpackhi_ps(r[2 * k], r[2 * k + 1]);
        }
        for (int k = 0; k < 2; ++k) {
            u[4 * k] = _mm256_shuffle_ps(t[4 * k], t[4 * k + 2], 0x44);
            u[4 * k + 1] = _mm256_shuffle_ps(t[4 * k], t[4 * k + 2], 0xEE);
            u[4 * k + 2] = _mm256_shuffle_ps(t[4 * k + 1], t[4 * k + 3], 0x44);
            u[4 * k + 3] = _mm256_shuffle_ps(t[4 * k + 1], t[4 * k + 3], 0xEE);
        }
        for (int k = 0; k < 4; ++k) {
            m[k] = _mm256_permute2f128_ps(u[k], u[k + 4], 0x20);
            m[k + 4] = _mm256_permute2f128_ps(u[k], u[k + 4], 0x31);
        }
        m[8] = _mm256_load_ps(ninth);
    }
    // Eight RGBA fp32 pixels of alpha 1: a 4 x 8 transpose (128-bit lane L of px[q] is pixel 4 L + q), then whole
    // vectors of two pixels where they are packed, else 16-byte pixels.
    static void storeRgba(uint8_t* o, size_t stride, const F rgb[3]) {
        const F a = _mm256_set1_ps(1.0f);
        const F t0 = _mm256_unpacklo_ps(rgb[0], rgb[1]), t1 = _mm256_unpackhi_ps(rgb[0], rgb[1]);
        const F t2 = _mm256_unpacklo_ps(rgb[2], a), t3 = _mm256_unpackhi_ps(rgb[2], a);
        const F px[4] = {_mm256_shuffle_ps(t0, t2, 0x44), _mm256_shuffle_ps(t0, t2, 0xEE), _mm256_shuffle_ps(t1, t3, 0x44),
                         _mm256_shuffle_ps(t1, t3, 0xEE)};
        if (stride == 16) {
            float* f = reinterpret_cast<float*>(o);
            _mm256_storeu_ps(f, _mm256_permute2f128_ps(px[0], px[1], 0x20));  // pixels 0, 1
            _mm256_storeu_ps(f + 8, _mm256_permute2f128_ps(px[2], px[3], 0x20));
            _mm256_storeu_ps(f + 16, _mm256_permute2f128_ps(px[0], px[1], 0x31));
            _mm256_storeu_ps(f + 24, _mm256_permute2f128_ps(px[2], px[3], 0x31));
            return;
        }
        for (int q = 0; q < 4; ++q) {
            _mm_storeu_ps(reinterpret_cast<float*>(o + size_t(q) * stride), _mm256_castps256_ps128(px[q]));
            _mm_storeu_ps(reinterpret_cast<float*>(o + size_t(4 + q) * stride), _mm256_extractf128_ps(px[q], 1));
        }
    }
    // Eight RGBA fp16 pixels: the inverse transpose, then whole 8-byte pixels.
    static constexpr bool kRgbaStores = true;
    static void storeHalfRgba(uint8_t* o, size_t stride, const F rgb[3]) {
        const __m128i r = toHalf(rgb[0]), g = toHalf(rgb[1]), b = toHalf(rgb[2]), a = _mm_set1_epi16(0x3C00);
        const __m128i rgLo = _mm_unpacklo_epi16(r, g), rgHi = _mm_unpackhi_epi16(r, g);
        const __m128i baLo = _mm_unpacklo_epi16(b, a), baHi = _mm_unpackhi_epi16(b, a);
        const __m128i px[4] = {_mm_unpacklo_epi32(rgLo, baLo), _mm_unpackhi_epi32(rgLo, baLo),
                               _mm_unpacklo_epi32(rgHi, baHi), _mm_unpackhi_epi32(rgHi, baHi)};  // pixels 2k, 2k + 1
        if (stride == 8) {
            for (int k = 0; k < 4; ++k) _mm_storeu_si128(reinterpret_cast<__m128i*>(o + 16 * k), px[k]);
            return;
        }
        for (int k = 0; k < 4; ++k) {
            _mm_storel_epi64(reinterpret_cast<__m128i*>(o + size_t(2 * k) * stride), px[k]);
            _mm_storeh_pd(reinterpret_cast<double*>(o + size_t(2 * k + 1) * stride), _mm_castsi128_pd(px[k]));
        }
    }
};

}  // namespace

namespace {
#include "simd_impl.h"

using Lanes = Interleave<8>;
constexpr Lanes::Tables kTables = Lanes::tables();

__m256i indices(const int32_t* table) { return _mm256_loadu_si256(reinterpret_cast<const __m256i*>(table)); }

// _mm256_blend_ps needs its mask as an immediate: one instantiation per (vector, component).
template <int S, int C>
__m256 blendFrom(__m256 into, __m256 v) {
    return _mm256_blend_ps(into, v, int(Lanes::kMask<S, C>));
}

void Avx2::deinterleave3(F a, F b, F c, F out[3]) {
    out[0] = _mm256_permutevar8x32_ps(blendFrom<2, 0>(blendFrom<1, 0>(a, b), c), indices(kTables.gather[0]));
    out[1] = _mm256_permutevar8x32_ps(blendFrom<2, 1>(blendFrom<1, 1>(a, b), c), indices(kTables.gather[1]));
    out[2] = _mm256_permutevar8x32_ps(blendFrom<2, 2>(blendFrom<1, 2>(a, b), c), indices(kTables.gather[2]));
}

void Avx2::interleave3(const F in[3], F out[3]) {
    F q[3];
    for (int k = 0; k < 3; ++k) q[k] = _mm256_permutevar8x32_ps(in[k], indices(kTables.scatter[k]));
    out[0] = blendFrom<0, 2>(blendFrom<0, 1>(q[0], q[1]), q[2]);
    out[1] = blendFrom<1, 2>(blendFrom<1, 1>(q[0], q[1]), q[2]);
    out[2] = blendFrom<2, 2>(blendFrom<2, 1>(q[0], q[1]), q[2]);
}
}  // namespace

void evalChunkAvx2(const NetworkView& net, const float* x, float* y, int count) { evalChunk<Avx2>(net, x, y, count); }

void halfToFloatF16c(const uint16_t* in, float* out, size_t n) {
    size_t i = 0;
    for (; i + 8 <= n; i += 8)
        _mm256_storeu_ps(out + i, _mm256_cvtph_ps(_mm_loadu_si128(reinterpret_cast<const __m128i*>(in + i))));
    for (; i < n; ++i) out[i] = _cvtsh_ss(in[i]);
}

void floatToHalfF16c(const float* in, uint16_t* out, size_t n) {
    // Saturate at 65504 first (format::floatToHalf's rule: values from 65520 up give 65504, not infinity);
    // the conversion rounds to nearest even, as format::floatToHalf does.
    const __m256 top = _mm256_set1_ps(65504.0f);
    size_t i = 0;
    for (; i + 8 <= n; i += 8)
        _mm_storeu_si128(reinterpret_cast<__m128i*>(out + i),
                         _mm256_cvtps_ph(_mm256_min_ps(_mm256_loadu_ps(in + i), top), _MM_FROUND_TO_NEAREST_INT | _MM_FROUND_NO_EXC));
    for (; i < n; ++i) out[i] = uint16_t(_cvtss_sh(in[i] < 65504.0f ? in[i] : 65504.0f, _MM_FROUND_TO_NEAREST_INT | _MM_FROUND_NO_EXC));
}

void evalBlocksAvx2(const BlockContext& ctx, size_t blocks, Deferred& def) {
    if (ctx.io.stride == 1)
        evalBlocks<Avx2, 1>(ctx, blocks, def);
    else
        evalBlocks<Avx2, 3>(ctx, blocks, def);
}

}  // namespace nrad::rt
