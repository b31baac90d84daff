// Mlp's mini-batch kernels (forwardBatch, backwardBatch) over an 8-lane type, included once per instruction set
// (mlp_batch_sse2.cpp, mlp_batch_avx2.cpp, each in its own namespace NRAD_MLP_KERNELS; mlp.cpp picks one at run
// time). Each lane does exactly the scalar operations (a multiply, then an add: no fused multiply-add) and every
// sum runs in the same order in each, so every instruction set gives the same bits as the per-sample pass.
#pragma once

#include <cstddef>
#include <vector>

#if defined(__SSE2__)
#include <emmintrin.h>
#include <xmmintrin.h>
#endif
#if defined(__AVX2__)
#include <immintrin.h>
#endif

#include "baker/nn/mlp_batch.h"

namespace nrad {
namespace NRAD_MLP_KERNELS {
constexpr int B = MlpBatchWorkspace::kMaxBatch;
constexpr int kLanes = 8;  // samples per vector below, and the partial sums of the per-parameter sums over the batch

// Eight float lanes: one AVX2 register, two SSE2 registers on x86-64 (every x86-64 has them), plain arrays
// elsewhere.
#if defined(__AVX2__)
struct V8 {
    __m256 v;
    __m128 lo() const { return _mm256_castps256_ps128(v); }
    __m128 hi() const { return _mm256_extractf128_ps(v, 1); }
};
inline V8 splat(float x) { return {_mm256_set1_ps(x)}; }
inline V8 load(const float* p) { return {_mm256_loadu_ps(p)}; }
inline void store(float* p, const V8& v) { _mm256_storeu_ps(p, v.v); }
inline V8 operator+(const V8& a, const V8& b) { return {_mm256_add_ps(a.v, b.v)}; }
inline V8 operator*(const V8& a, const V8& b) { return {_mm256_mul_ps(a.v, b.v)}; }
// p > 0 ? v : 0, lane by lane (NaN in p gives 0, as the comparison does).
inline V8 whereAboveZero(const V8& p, const V8& v) { return {_mm256_and_ps(v.v, _mm256_cmp_ps(p.v, _mm256_setzero_ps(), _CMP_GT_OQ))}; }
#elif defined(__SSE2__)
struct V8 {
    __m128 l, h;
    __m128 lo() const { return l; }
    __m128 hi() const { return h; }
};
inline V8 splat(float x) { return {_mm_set1_ps(x), _mm_set1_ps(x)}; }
inline V8 load(const float* p) { return {_mm_loadu_ps(p), _mm_loadu_ps(p + 4)}; }
inline void store(float* p, const V8& v) {
    _mm_storeu_ps(p, v.l);
    _mm_storeu_ps(p + 4, v.h);
}
inline V8 operator+(const V8& a, const V8& b) { return {_mm_add_ps(a.l, b.l), _mm_add_ps(a.h, b.h)}; }
inline V8 operator*(const V8& a, const V8& b) { return {_mm_mul_ps(a.l, b.l), _mm_mul_ps(a.h, b.h)}; }
// p > 0 ? v : 0, lane by lane (NaN in p gives 0, as the comparison does).
inline V8 whereAboveZero(const V8& p, const V8& v) {
    const __m128 z = _mm_setzero_ps();
    return {_mm_and_ps(v.l, _mm_cmpgt_ps(p.l, z)), _mm_and_ps(v.h, _mm_cmpgt_ps(p.h, z))};
}
#else
struct V8 {
    float f[kLanes];
};
inline V8 splat(float x) {
    V8 v;
    for (float& f : v.f) f = x;
    return v;
}
inline V8 load(const float* p) {
    V8 v;
    for (int j = 0; j < kLanes; ++j) v.f[j] = p[j];
    return v;
}
inline void store(float* p, const V8& v) {
    for (int j = 0; j < kLanes; ++j) p[j] = v.f[j];
}
inline V8 operator+(const V8& a, const V8& b) {
    V8 v;
    for (int j = 0; j < kLanes; ++j) v.f[j] = a.f[j] + b.f[j];
    return v;
}
inline V8 operator*(const V8& a, const V8& b) {
    V8 v;
    for (int j = 0; j < kLanes; ++j) v.f[j] = a.f[j] * b.f[j];
    return v;
}
inline V8 whereAboveZero(const V8& p, const V8& v) {
    V8 r;
    for (int j = 0; j < kLanes; ++j) r.f[j] = p.f[j] > 0.0f ? v.f[j] : 0.0f;
    return r;
}
#endif

// The lanes added up in lane order, from zero.
inline float sumInOrder(const V8& v) {
    float lanes[kLanes];
    store(lanes, v);
    float s = 0.0f;
    for (int j = 0; j < kLanes; ++j) s += lanes[j];
    return s;
}

// out[q] = sumInOrder(v[q]) for q < count: on SSE2 four at a time, transposed so that each lane adds up one
// vector's lanes (the same additions in the same order).
inline void sumsInOrder(const V8* v, int count, float* out) {
    int q = 0;
#if defined(__SSE2__)
    for (; q + 4 <= count; q += 4) {
        __m128 a0 = v[q].lo(), a1 = v[q + 1].lo(), a2 = v[q + 2].lo(), a3 = v[q + 3].lo();
        __m128 b0 = v[q].hi(), b1 = v[q + 1].hi(), b2 = v[q + 2].hi(), b3 = v[q + 3].hi();
        _MM_TRANSPOSE4_PS(a0, a1, a2, a3);
        _MM_TRANSPOSE4_PS(b0, b1, b2, b3);
        __m128 s = _mm_setzero_ps();
        s = _mm_add_ps(s, a0);
        s = _mm_add_ps(s, a1);
        s = _mm_add_ps(s, a2);
        s = _mm_add_ps(s, a3);
        s = _mm_add_ps(s, b0);
        s = _mm_add_ps(s, b1);
        s = _mm_add_ps(s, b2);
        s = _mm_add_ps(s, b3);
        _mm_storeu_ps(out + q, s);
    }
#endif
    for (; q < count; ++q) out[q] = sumInOrder(v[q]);
}

// Mlp::forwardBatch on a prepared workspace (prepareBatch; ws.count set): the network of `shape` with `params`
// (each layer's at offsets[l]).
void forwardBatch(const NetworkShape& shape, const std::vector<float>& params, const std::vector<size_t>& offsets, const float* x,
                  int count, MlpBatchWorkspace& ws) {
    const int n = (count + kLanes - 1) / kLanes * kLanes;  // padded samples hold zeros: finite, no gradient
    for (int i = 0; i < shape.inputs; ++i) {
        float* v = ws.value(0, i);
        for (int k = 0; k < count; ++k) v[k] = x[size_t(k) * size_t(shape.inputs) + size_t(i)];
        for (int k = count; k < n; ++k) v[k] = 0.0f;
    }
    int in = shape.inputs;
    for (size_t l = 0; l < (shape.hidden.size() + 1); ++l) {
        const bool last = l + 1 == (shape.hidden.size() + 1);
        const int out = last ? shape.outputs : shape.hidden[l];
        const float* W = params.data() + offsets[l];
        const float* b = W + size_t(out) * size_t(in);
        const float* prev = ws.value(l, 0);
        for (int o = 0; o < out; ++o) {
            float* a = ws.value(l + 1, o);
            const float* w = W + size_t(o) * size_t(in);
            // kLanes samples at a time, each one's sum in a register from the bias up in input order.
            for (int k0 = 0; k0 < n; k0 += kLanes) {
                V8 acc = splat(b[o]);
                for (int i = 0; i < in; ++i) acc = acc + splat(w[i]) * load(prev + size_t(i) * B + size_t(k0));
                store(a + k0, last ? acc : whereAboveZero(acc, acc));
            }
        }
        in = out;
    }
}

// Mlp::backwardBatch: adds the batch's summed gradient to `grad`.
void backwardBatch(const NetworkShape& shape, const std::vector<float>& params, const std::vector<size_t>& offsets,
                   MlpBatchWorkspace& ws, float* grad) {
    const int n = (ws.count + kLanes - 1) / kLanes * kLanes;
    const size_t L = (shape.hidden.size() + 1);
    for (int o = 0; o < shape.outputs; ++o) {
        float* d = ws.delta(L, o);
        for (int k = ws.count; k < n; ++k) d[k] = 0.0f;
    }
    for (size_t l = L; l-- > 0;) {
        const int out = l + 1 == L ? shape.outputs : shape.hidden[l];
        const int in = l == 0 ? shape.inputs : shape.hidden[l - 1];
        const float* W = params.data() + offsets[l];
        float* gW = grad + offsets[l];
        float* gb = gW + size_t(out) * size_t(in);
        const float* prev = ws.value(l, 0);
        for (int o = 0; o < out; ++o) {
            // Every weight's and the bias's sum over the batch in kLanes partial sums, added up in lane order;
            // four weights at a time, their partial sums in registers.
            const float* d = ws.delta(l + 1, o);
            int g = 0;
            for (; g + 4 <= in; g += 4) {
                const float *p0 = prev + size_t(g) * B, *p1 = p0 + B, *p2 = p1 + B, *p3 = p2 + B;
                V8 acc[4] = {splat(0.0f), splat(0.0f), splat(0.0f), splat(0.0f)};
                for (int k = 0; k < n; k += kLanes) {
                    const V8 dk = load(d + k);
                    acc[0] = acc[0] + dk * load(p0 + k);
                    acc[1] = acc[1] + dk * load(p1 + k);
                    acc[2] = acc[2] + dk * load(p2 + k);
                    acc[3] = acc[3] + dk * load(p3 + k);
                }
                float sums[4];
                sumsInOrder(acc, 4, sums);
                for (int q = 0; q < 4; ++q) gW[size_t(o) * size_t(in) + size_t(g + q)] += sums[q];
            }
            for (; g < in; ++g) {
                const float* pg = prev + size_t(g) * B;
                V8 acc = splat(0.0f);
                for (int k = 0; k < n; k += kLanes) acc = acc + load(d + k) * load(pg + k);
                gW[size_t(o) * size_t(in) + size_t(g)] += sumInOrder(acc);
            }
            V8 bias = splat(0.0f);
            for (int k = 0; k < n; k += kLanes) bias = bias + load(d + k);
            gb[o] += sumInOrder(bias);
        }
        if (l == 0) break;
        // The previous layer's deltas: each sample's sum over outputs in output order, in a register, zero for
        // inactive units (ReLU'(z) = 0).
        const float* next = ws.delta(l + 1, 0);
        for (int i = 0; i < in; ++i) {
            float* back = ws.delta(l, i);
            const float* p = ws.value(l, i);
            for (int k0 = 0; k0 < n; k0 += kLanes) {
                V8 acc = splat(0.0f);
                for (int o = 0; o < out; ++o) acc = acc + splat(W[size_t(o) * size_t(in) + size_t(i)]) * load(next + size_t(o) * B + size_t(k0));
                store(back + k0, whereAboveZero(load(p + k0), acc));
            }
        }
    }
}

}  // namespace NRAD_MLP_KERNELS
}  // namespace nrad
