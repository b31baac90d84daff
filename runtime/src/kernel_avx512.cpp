// AVX-512F kernels: 16 points per vector. Compiled with -mavx512f; called only after the CPU was checked.
// GCC 12's AVX-512 intrinsics pass _mm512_undefined_ps() as the masked-off source, which its
// -Wmaybe-uninitialized / -Wuninitialized report as a use of an uninitialised value (a false positive).
#if defined(__GNUC__) && !defined(__clang__)
#pragma GCC diagnostic ignored "-Wmaybe-uninitialized"
#pragma GCC diagnostic ignored "-Wuninitialized"
#endif
#include <immintrin.h>

#include "kernels.h"

// FMA3 for Avx512Narrow's 256-bit multiply-adds: every CPU with AVX-512F has it (-mavx512f does not imply it).
#if defined(__clang__)
#pragma clang attribute push(__attribute__((target("fma"))), apply_to = function)
#elif defined(__GNUC__)
#pragma GCC target("fma")
#endif

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
    static __m256i toHalf(F v) {  // floatToHalfF16c's rule
        return _mm512_cvtps_ph(_mm512_min_ps(v, _mm512_set1_ps(65504.0f)), _MM_FROUND_TO_NEAREST_INT | _MM_FROUND_NO_EXC);
    }
    static void storeHalf(uint16_t* p, F v) { _mm256_storeu_si256(reinterpret_cast<__m256i*>(p), toHalf(v)); }

    // The G-buffer readers and writer use AVX-512F alone (the CPU check tests nothing else): no 16-bit shuffles of
    // 512-bit vectors (AVX-512BW), 256-bit AVX2 ones instead, which -mavx512f enables. Rows are assembled by inserts
    // and masked broadcasts straight from memory (a load and one operation each; gathers were slower: a 1080p frame
    // 23.7 ms against 18.5 on this session's Cascade Lake). Points are read in four runs, point k + 4 m at sk + m q
    // (sk: point k, q: four strides), so that the addresses are base + index x scale forms of three registers
    // rather than sixteen live pointers.
    template <class T>
    static const T* at(const uint8_t* p) { return reinterpret_cast<const T*>(p); }
    // Sixteen points' x y z w (16 bytes from each; w unused) as four rows, lane j of row k holding point 4 j + k,
    // transposed in each 128-bit lane as Avx2::loadStrided3 does.
    static void transpose4(const F r[4], F v[3]) {
        const F t0 = _mm512_unpacklo_ps(r[0], r[1]), t1 = _mm512_unpackhi_ps(r[0], r[1]);  // x0 x1 y0 y1, z0 z1 w0 w1
        const F t2 = _mm512_unpacklo_ps(r[2], r[3]), t3 = _mm512_unpackhi_ps(r[2], r[3]);
        v[0] = _mm512_shuffle_ps(t0, t2, _MM_SHUFFLE(1, 0, 1, 0));
        v[1] = _mm512_shuffle_ps(t0, t2, _MM_SHUFFLE(3, 2, 3, 2));
        v[2] = _mm512_shuffle_ps(t1, t3, _MM_SHUFFLE(1, 0, 1, 0));
    }
    // Sixteen points' x y z (and the next 4 bytes): 16-byte loads into the rows of transpose4.
    static constexpr bool kStridedLoads = true;
    static void loadStrided3(const uint8_t* s, size_t stride, F v[3]) {
        const size_t q = 4 * stride, q3 = 3 * q;
        F r[4];
        for (int k = 0; k < 4; ++k, s += stride) {
            r[k] = _mm512_castps128_ps512(_mm_loadu_ps(at<float>(s)));
            r[k] = _mm512_insertf32x4(r[k], _mm_loadu_ps(at<float>(s + q)), 1);
            r[k] = _mm512_insertf32x4(r[k], _mm_loadu_ps(at<float>(s + 2 * q)), 2);
            r[k] = _mm512_insertf32x4(r[k], _mm_loadu_ps(at<float>(s + q3)), 3);
        }
        transpose4(r, v);
    }
    // Sixteen points' x y z (and the next 2 bytes) in fp16: 8-byte loads, four points per 256-bit row (qword j of
    // row k: point 4 j + k) converted to fp32, a point's x y z w in each 128-bit lane as loadStrided3's rows; then
    // transpose4.
    static void loadStrided3Half(const uint8_t* s, size_t stride, F v[3]) {
        if (stride == 8) {  // packed 8-byte points (x y z w): 128 bytes in two loads
            const __m512i lo = _mm512_loadu_si512(s), hi = _mm512_loadu_si512(s + 64);
            const F r[4] = {_mm512_cvtph_ps(_mm512_castsi512_si256(lo)), _mm512_cvtph_ps(_mm512_extracti64x4_epi64(lo, 1)),
                            _mm512_cvtph_ps(_mm512_castsi512_si256(hi)), _mm512_cvtph_ps(_mm512_extracti64x4_epi64(hi, 1))};
            // Lane j of r[k] holds point 4 k + j (transpose4 expects 4 j + k): transpose4 leaves point 4 k + j at
            // element 4 j + k, and one permute a component puts the points in order.
            F t[3];
            transpose4(r, t);
            const __m512i order = _mm512_setr_epi32(0, 4, 8, 12, 1, 5, 9, 13, 2, 6, 10, 14, 3, 7, 11, 15);
            for (int k = 0; k < 3; ++k) v[k] = _mm512_permutexvar_ps(order, t[k]);
            return;
        }
        const size_t q = 4 * stride, q3 = 3 * q;
        auto point = [](const uint8_t* p) { return _mm_loadl_epi64(at<__m128i>(p)); };
        __m512i rows[2];  // rows 2 h and 2 h + 1 in the low and high halves of rows[h]
        for (int h = 0; h < 2; ++h) {
            const uint8_t* lo = s + size_t(2 * h) * stride;
            const uint8_t* hi = lo + stride;
            __m512i x = _mm512_castsi128_si512(point(lo));
            x = _mm512_mask_broadcastq_epi64(x, 0x02, point(lo + q));
            x = _mm512_mask_broadcastq_epi64(x, 0x04, point(lo + 2 * q));
            x = _mm512_mask_broadcastq_epi64(x, 0x08, point(lo + q3));
            x = _mm512_mask_broadcastq_epi64(x, 0x10, point(hi));
            x = _mm512_mask_broadcastq_epi64(x, 0x20, point(hi + q));
            x = _mm512_mask_broadcastq_epi64(x, 0x40, point(hi + 2 * q));
            rows[h] = _mm512_mask_broadcastq_epi64(x, 0x80, point(hi + q3));
        }
        const F r[4] = {_mm512_cvtph_ps(_mm512_castsi512_si256(rows[0])), _mm512_cvtph_ps(_mm512_extracti64x4_epi64(rows[0], 1)),
                        _mm512_cvtph_ps(_mm512_castsi512_si256(rows[1])), _mm512_cvtph_ps(_mm512_extracti64x4_epi64(rows[1], 1))};
        transpose4(r, v);
    }
    // Sixteen NradSurfaces' nine floats: the first eight of each (32 bytes, inside the surface) as two 8 x 8
    // transposes side by side (Avx2::loadSurfaces in each 256-bit half), the ninth by masked broadcasts. Row i
    // holds surfaces l and l + 4 (l = i, or i + 4 for i >= 4), so that the last step's 128-bit lane shuffle
    // leaves the surfaces in order.
    static constexpr bool kSurfaceLoads = true;
    static void loadSurfaces(const uint8_t* s, size_t stride, F m[9]) {
        const size_t q = 4 * stride, q3 = 3 * q;
        F r[8];
        F ninth = _mm512_setzero_ps();
        const uint8_t* sk = s;
        for (int k = 0; k < 4; ++k, sk += stride) {  // surfaces k, k + 4, k + 8, k + 12
            for (int h = 0; h < 2; ++h) {
                const uint8_t* row = sk + (h ? 2 * q : 0);
                const __m512d lo = _mm512_castpd256_pd512(_mm256_loadu_pd(at<double>(row)));
                r[k + 4 * h] = _mm512_castpd_ps(_mm512_mask_broadcast_f64x4(lo, 0xF0, _mm256_loadu_pd(at<double>(row + q))));
            }
            ninth = _mm512_mask_broadcastss_ps(ninth, __mmask16(1u << k), _mm_load_ss(at<float>(sk) + 8));
            ninth = _mm512_mask_broadcastss_ps(ninth, __mmask16(1u << (k + 4)), _mm_load_ss(at<float>(sk + q) + 8));
            ninth = _mm512_mask_broadcastss_ps(ninth, __mmask16(1u << (k + 8)), _mm_load_ss(at<float>(sk + 2 * q) + 8));
            ninth = _mm512_mask_broadcastss_ps(ninth, __mmask16(1u << (k + 12)), _mm_load_ss(at<float>(sk + q3) + 8));
        }
        F t[8], u[8];
        for (int k = 0; k < 4; ++k) {
            t[2 * k] = _mm512_unpacklo_ps(r[2 * k], r[2 * k + 1]);
            t[2 * k + 1] = _mm512_unpackhi_ps(r[2 * k], r[2 * k + 1]);
        }
        for (int k = 0; k < 2; ++k) {
            u[4 * k] = _mm512_shuffle_ps(t[4 * k], t[4 * k + 2], 0x44);
            u[4 * k + 1] = _mm512_shuffle_ps(t[4 * k], t[4 * k + 2], 0xEE);
            u[4 * k + 2] = _mm512_shuffle_ps(t[4 * k + 1], t[4 * k + 3], 0x44);
            u[4 * k + 3] = _mm512_shuffle_ps(t[4 * k + 1], t[4 * k + 3], 0xEE);
        }
        for (int k = 0; k < 4; ++k) {  // 128-bit lanes 0 and 2 of u[k], then of u[k + 4]; 1 and 3 likewise
            m[k] = _mm512_shuffle_f32x4(u[k], u[k + 4], 0x88);
            m[k + 4] = _mm512_shuffle_f32x4(u[k], u[k + 4], 0xDD);
        }
        m[8] = ninth;
    }
    // Sixteen RGBA fp32 pixels of alpha 1: a 4 x 16 transpose (after the unpacks and shuffles, 128-bit lane L of
    // px[q] is pixel 4 L + q), then whole vectors of four pixels where they are packed, else 16-byte pixels.
    static void storeRgba(uint8_t* o, size_t stride, const F rgb[3]) {
        const F a = _mm512_set1_ps(1.0f);
        const F t0 = _mm512_unpacklo_ps(rgb[0], rgb[1]), t1 = _mm512_unpackhi_ps(rgb[0], rgb[1]);
        const F t2 = _mm512_unpacklo_ps(rgb[2], a), t3 = _mm512_unpackhi_ps(rgb[2], a);
        const F px[4] = {_mm512_shuffle_ps(t0, t2, 0x44), _mm512_shuffle_ps(t0, t2, 0xEE), _mm512_shuffle_ps(t1, t3, 0x44),
                         _mm512_shuffle_ps(t1, t3, 0xEE)};
        if (stride == 16) {
            const F a0 = _mm512_shuffle_f32x4(px[0], px[1], _MM_SHUFFLE(2, 0, 2, 0)), a1 = _mm512_shuffle_f32x4(px[0], px[1], _MM_SHUFFLE(3, 1, 3, 1));
            const F b0 = _mm512_shuffle_f32x4(px[2], px[3], _MM_SHUFFLE(2, 0, 2, 0)), b1 = _mm512_shuffle_f32x4(px[2], px[3], _MM_SHUFFLE(3, 1, 3, 1));
            float* f = reinterpret_cast<float*>(o);
            _mm512_storeu_ps(f, _mm512_shuffle_f32x4(a0, b0, _MM_SHUFFLE(2, 0, 2, 0)));  // pixels 0-3
            _mm512_storeu_ps(f + 16, _mm512_shuffle_f32x4(a1, b1, _MM_SHUFFLE(2, 0, 2, 0)));
            _mm512_storeu_ps(f + 32, _mm512_shuffle_f32x4(a0, b0, _MM_SHUFFLE(3, 1, 3, 1)));
            _mm512_storeu_ps(f + 48, _mm512_shuffle_f32x4(a1, b1, _MM_SHUFFLE(3, 1, 3, 1)));
            return;
        }
        for (int q = 0; q < 4; ++q) {
            _mm_storeu_ps(reinterpret_cast<float*>(o + size_t(q) * stride), _mm512_castps512_ps128(px[q]));
            _mm_storeu_ps(reinterpret_cast<float*>(o + size_t(4 + q) * stride), _mm512_extractf32x4_ps(px[q], 1));
            _mm_storeu_ps(reinterpret_cast<float*>(o + size_t(8 + q) * stride), _mm512_extractf32x4_ps(px[q], 2));
            _mm_storeu_ps(reinterpret_cast<float*>(o + size_t(12 + q) * stride), _mm512_extractf32x4_ps(px[q], 3));
        }
    }
    // Sixteen RGBA fp16 pixels: Avx2::storeHalfRgba's inverse transpose in each 128-bit lane of 256-bit vectors
    // (pixels 0-7 in the low lanes, 8-15 in the high), then whole 8-byte pixels.
    static constexpr bool kRgbaStores = true;
    static void storeHalfRgba(uint8_t* o, size_t stride, const F rgb[3]) {
        const __m256i r = toHalf(rgb[0]), g = toHalf(rgb[1]), b = toHalf(rgb[2]), a = _mm256_set1_epi16(0x3C00);
        const __m256i rgLo = _mm256_unpacklo_epi16(r, g), rgHi = _mm256_unpackhi_epi16(r, g);
        const __m256i baLo = _mm256_unpacklo_epi16(b, a), baHi = _mm256_unpackhi_epi16(b, a);
        const __m256i px[4] = {_mm256_unpacklo_epi32(rgLo, baLo), _mm256_unpackhi_epi32(rgLo, baLo),
                               _mm256_unpacklo_epi32(rgHi, baHi), _mm256_unpackhi_epi32(rgHi, baHi)};  // 2k, 2k + 1 | 2k + 8, 2k + 9
        if (stride == 8) {
            for (int k = 0; k < 4; ++k) {
                _mm_storeu_si128(reinterpret_cast<__m128i*>(o + 16 * k), _mm256_castsi256_si128(px[k]));
                _mm_storeu_si128(reinterpret_cast<__m128i*>(o + 64 + 16 * k), _mm256_extracti128_si256(px[k], 1));
            }
            return;
        }
        for (int k = 0; k < 4; ++k)
            for (int h = 0; h < 2; ++h) {
                const __m128i two = h ? _mm256_extracti128_si256(px[k], 1) : _mm256_castsi256_si128(px[k]);
                _mm_storel_epi64(reinterpret_cast<__m128i*>(o + size_t(2 * k + 8 * h) * stride), two);
                _mm_storeh_pd(reinterpret_cast<double*>(o + size_t(2 * k + 8 * h + 1) * stride), _mm_castsi128_pd(two));
            }
    }
};

// Small chunks (a single point's call, a few points of one network) with 256-bit vectors and the same arithmetic
// as Avx512 lane for lane: the 32-register 9-9-3 evaluation (kRegisters), the same operations in the same order,
// 2^n by its exponent bits (exact for the exp's n in [-126, 127], as scalef). 512-bit multiply-adds lower the
// core's clock on AVX-512 CPUs for a while after they run, which made one point per call slower with this kernel
// than with AVX2 when it evaluated a 16-lane vector for one point (docs/design.md).
struct Avx512Narrow {
    using F = __m256;
    static constexpr int kRegisters = 32;
    static constexpr int W = 8;
    static F load(const float* p) { return _mm256_loadu_ps(p); }
    static void store(float* p, F v) { _mm256_storeu_ps(p, v); }
    static F set1(float x) { return _mm256_set1_ps(x); }
    static F zero() { return _mm256_setzero_ps(); }
    static F add(F a, F b) { return _mm256_add_ps(a, b); }
    static F sub(F a, F b) { return _mm256_sub_ps(a, b); }
    static F mul(F a, F b) { return _mm256_mul_ps(a, b); }
    static F fmadd(F a, F b, F c) { return _mm256_fmadd_ps(a, b, c); }
    static F fnmadd(F a, F b, F c) { return _mm256_fnmadd_ps(a, b, c); }
    static F min(F a, F b) { return _mm256_min_ps(a, b); }
    static F max(F a, F b) { return _mm256_max_ps(a, b); }
    static F roundNearest(F a) { return _mm256_round_ps(a, _MM_FROUND_TO_NEAREST_INT | _MM_FROUND_NO_EXC); }
    static F timesPow2(F q, F n) {
        return _mm256_mul_ps(q, _mm256_castsi256_ps(_mm256_slli_epi32(_mm256_add_epi32(_mm256_cvtps_epi32(n), _mm256_set1_epi32(127)), 23)));
    }
};

}  // namespace

namespace {
#include "simd_impl.h"

// deinterleave3 / interleave3 as two-source permutes: each output vector is one permute of two inputs with the
// third's lanes permuted into it under a mask (two shuffles per vector where blends took three operations).
// Element e of the interleaved vectors (x0 y0 z0 x1 ...) is component e % 3 of point e / 3.
struct Permutes {
    int32_t gather[3][16];  // component c: lanes from a | b (element index < 32)
    int32_t gatherC[3][16];  // ... and from c (element index - 32)
    unsigned fromC[3];
    int32_t scatter[3][16];  // vector s: lanes from x | y (point + 16 component)
    int32_t scatterZ[3][16];  // ... and from z (point)
    unsigned fromZ[3];
};

constexpr Permutes permutes() {
    Permutes t{};
    for (int c = 0; c < 3; ++c)
        for (int k = 0; k < 16; ++k) {
            const int e = 3 * k + c;
            if (e < 32) t.gather[c][k] = e;
            else t.gatherC[c][k] = e - 32, t.fromC[c] |= 1u << k;
        }
    for (int s = 0; s < 3; ++s)
        for (int l = 0; l < 16; ++l) {
            const int e = 16 * s + l, point = e / 3, c = e % 3;
            if (c < 2) t.scatter[s][l] = point + 16 * c;
            else t.scatterZ[s][l] = point, t.fromZ[s] |= 1u << l;
        }
    return t;
}
constexpr Permutes kPermutes = permutes();

void Avx512::deinterleave3(F a, F b, F c, F out[3]) {
    for (int k = 0; k < 3; ++k)
        out[k] = _mm512_mask_permutexvar_ps(_mm512_permutex2var_ps(a, _mm512_loadu_si512(kPermutes.gather[k]), b),
                                            __mmask16(kPermutes.fromC[k]), _mm512_loadu_si512(kPermutes.gatherC[k]), c);
}

void Avx512::interleave3(const F in[3], F out[3]) {
    for (int s = 0; s < 3; ++s)
        out[s] = _mm512_mask_permutexvar_ps(_mm512_permutex2var_ps(in[0], _mm512_loadu_si512(kPermutes.scatter[s]), in[1]),
                                            __mmask16(kPermutes.fromZ[s]), _mm512_loadu_si512(kPermutes.scatterZ[s]), in[2]);
}
}  // namespace

void evalChunkAvx512(const NetworkView& net, const float* x, float* y, int count) {
    if (count <= Avx512Narrow::W)
        evalChunk<Avx512Narrow>(net, x, y, count);
    else
        evalChunk<Avx512>(net, x, y, count);
}

void evalBlocksAvx512(const BlockContext& ctx, size_t blocks, Deferred& def) {
    if (ctx.io.stride == 1)
        evalBlocks<Avx512, 1>(ctx, blocks, def);
    else
        evalBlocks<Avx512, 3>(ctx, blocks, def);
}

#if defined(__clang__)
#pragma clang attribute pop
#endif

}  // namespace nrad::rt
