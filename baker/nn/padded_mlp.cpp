// The light selector's network: fixed-width layers in vectors of 16 floats, compiled for several targets.
#include "baker/nn/padded_mlp.h"

#include <algorithm>
#include <cmath>

#include "baker/nn/random.h"

namespace nrad {

namespace {

constexpr int kIn = PaddedMlp::kInputs, kHid = PaddedMlp::kHidden;

// The layers, compiled for AVX-512 and AVX2+FMA as well as the baseline and picked when the program loads
// (GCC's function multi-versioning; the loops over 64 outputs vectorise). Same machine, same code path:
// results stay deterministic.
#if defined(__x86_64__) && defined(__GNUC__) && !defined(__clang__)
#define NRAD_NN_CLONES __attribute__((target_clones("arch=x86-64-v4", "arch=x86-64-v3", "default")))
#else
#define NRAD_NN_CLONES
#endif
// Helpers are inlined into each clone so they are compiled for its target too.
#if defined(__GNUC__)
#define NRAD_NN_INLINE inline __attribute__((always_inline))
#else
#define NRAD_NN_INLINE inline
#endif

// out = relu(bias + sum_i in[i] W[i]); accumulators are locals so they stay in registers (no aliasing with the
// weights). No test for zero inputs: with ReLU inputs it mispredicts half the time and costs more than it saves.
// Generic vectors of 16 floats (GCC vector extensions): each clone maps them onto its own registers. S partial
// sums (rows i, i + S, ... go to sum i mod S) split the chain of dependent FMAs that bounds a matrix-vector
// product: at least 8 independent chains in all, so narrow layers (the output) get more partial sums.
typedef float Vec16 __attribute__((vector_size(64)));

template <int N, int InCount, bool Relu>
NRAD_NN_INLINE void dense(const float* __restrict W, const float* __restrict bias, const float* __restrict in,
                           float* __restrict out) {
    constexpr int V = N / 16;
    constexpr int S = V >= 4 ? 2 : 8 / V;
    Vec16 acc[S][V];
#pragma GCC unroll 8
    for (int v = 0; v < V; ++v) {
        __builtin_memcpy(&acc[0][v], bias + 16 * v, sizeof(Vec16));
#pragma GCC unroll 8
        for (int k = 1; k < S; ++k) acc[k][v] = Vec16{};
    }
    constexpr int Tail = InCount - InCount % S;
    for (int i = 0; i < Tail; i += S) {
#pragma GCC unroll 8
        for (int k = 0; k < S; ++k) {
            const float* __restrict row = W + (i + k) * N;
            Vec16 x = Vec16{} + in[i + k];
#pragma GCC unroll 8
            for (int v = 0; v < V; ++v) {
                Vec16 w;
                __builtin_memcpy(&w, row + 16 * v, sizeof(Vec16));
                acc[k][v] += x * w;
            }
        }
    }
    for (int i = Tail; i < InCount; ++i) {
        const float* __restrict row = W + i * N;
        Vec16 x = Vec16{} + in[i];
#pragma GCC unroll 8
        for (int v = 0; v < V; ++v) {
            Vec16 w;
            __builtin_memcpy(&w, row + 16 * v, sizeof(Vec16));
            acc[0][v] += x * w;
        }
    }
#pragma GCC unroll 8
    for (int v = 0; v < V; ++v) {
        Vec16 r = acc[0][v];
#pragma GCC unroll 8
        for (int k = 1; k < S; ++k) r += acc[k][v];
        if (Relu) r = r > Vec16{} ? r : Vec16{};
        __builtin_memcpy(out + 16 * v, &r, sizeof(Vec16));
    }
}

NRAD_NN_CLONES void forwardLayers(const float* P, int Kp, const float* x, PaddedMlp::Activations& a) {
    const float* W1 = P;
    const float* B1 = W1 + kIn * kHid;
    const float* W2 = B1 + kHid;
    const float* B2 = W2 + kHid * kHid;
    const float* W3 = B2 + kHid;
    const float* B3 = W3 + kHid * Kp;
    dense<kHid, kIn, true>(W1, B1, x, a.h1);
    dense<kHid, kHid, true>(W2, B2, a.h1, a.h2);
    switch (Kp) {  // the output rows are padded to one of these widths
        case 16: dense<16, kHid, false>(W3, B3, a.h2, a.logits); break;
        case 32: dense<32, kHid, false>(W3, B3, a.h2, a.logits); break;
        default: dense<64, kHid, false>(W3, B3, a.h2, a.logits); break;
    }
}

// Sum of a vector's lanes in lane order (a fixed order: the same bits on every run of one code path).
NRAD_NN_INLINE float laneSum(const Vec16& v) {
    float s = 0.0f;
#pragma GCC unroll 16
    for (int l = 0; l < 16; ++l) s += v[l];
    return s;
}

// Vectors pass by reference: a 64-byte vector by value would change the ABI between the clones.
NRAD_NN_INLINE void load16(Vec16& v, const float* p) { __builtin_memcpy(&v, p, sizeof(Vec16)); }

NRAD_NN_INLINE void addTo16(float* p, const Vec16& v) {
    Vec16 x;
    load16(x, p);
    x += v;
    __builtin_memcpy(p, &x, sizeof(Vec16));
}

NRAD_NN_INLINE void fmaRow(const float* p, const Vec16& a, Vec16& s) {
    Vec16 w;
    load16(w, p);
    s += w * a;
}

// One row of a layer's backward pass: g += h delta (the weight gradient of input h) and the row's dot product
// with delta (the input's delta before its ReLU), for V vectors of 16 outputs.
template <int V>
NRAD_NN_INLINE float backRow(const float* row, float* g, float h, const Vec16* delta) {
    Vec16 hv = Vec16{} + h, s = Vec16{};
#pragma GCC unroll 4
    for (int v = 0; v < V; ++v) {
        addTo16(g + 16 * v, hv * delta[v]);
        fmaRow(row + 16 * v, delta[v], s);
    }
    return laneSum(s);
}

// dLoss/dParams for one input, in vectors of 16 over each layer's outputs (the sums over outputs that give
// the previous layer's deltas are kept in vector lanes and added up at the end of each row).
template <int K>
NRAD_NN_INLINE void backwardPadded(const float* P, const float* x, const PaddedMlp::Activations& a, const float* dLogits,
                                    float* grad) {
    constexpr int VK = K / 16, VH = kHid / 16;
    const size_t w1 = 0, b1 = kIn * kHid, w2 = b1 + kHid, b2 = w2 + kHid * kHid,
                 w3 = b2 + kHid, b3 = w3 + size_t(kHid) * size_t(K);
    alignas(64) float d2[kHid], d1[kHid];
    Vec16 dl[VK];
#pragma GCC unroll 4
    for (int v = 0; v < VK; ++v) {
        load16(dl[v], dLogits + 16 * v);
        addTo16(grad + b3 + 16 * v, dl[v]);
    }
    for (int i = 0; i < kHid; ++i) {
        float s = backRow<VK>(P + w3 + size_t(i) * K, grad + w3 + size_t(i) * K, a.h2[i], dl);
        d2[i] = a.h2[i] > 0.0f ? s : 0.0f;
    }
    Vec16 d2v[VH];
#pragma GCC unroll 4
    for (int v = 0; v < VH; ++v) {
        load16(d2v[v], d2 + 16 * v);
        addTo16(grad + b2 + 16 * v, d2v[v]);
    }
    for (int i = 0; i < kHid; ++i)  // rows of inactive units add nothing to the gradient: skipped
        d1[i] = a.h1[i] > 0.0f ? backRow<VH>(P + w2 + size_t(i) * kHid, grad + w2 + size_t(i) * kHid, a.h1[i], d2v)
                               : 0.0f;
    Vec16 d1v[VH];
#pragma GCC unroll 4
    for (int v = 0; v < VH; ++v) {
        load16(d1v[v], d1 + 16 * v);
        addTo16(grad + b1 + 16 * v, d1v[v]);
    }
    for (int i = 0; i < kIn; ++i) {
        Vec16 xi = Vec16{} + x[i];
#pragma GCC unroll 4
        for (int v = 0; v < VH; ++v) addTo16(grad + w1 + size_t(i) * kHid + 16 * v, xi * d1v[v]);
    }
}

NRAD_NN_CLONES void backwardLayers(const float* P, int Kp, const float* x, const PaddedMlp::Activations& a,
                                    const float* dLogits, float* grad) {
    switch (Kp) {  // the output rows are padded to one of these widths
        case 16: backwardPadded<16>(P, x, a, dLogits, grad); break;
        case 32: backwardPadded<32>(P, x, a, dLogits, grad); break;
        default: backwardPadded<64>(P, x, a, dLogits, grad); break;
    }
}

}  // namespace

PaddedMlp::PaddedMlp(int outputs, uint64_t seed)
    : outputs_(std::clamp(outputs, 1, kMaxOutputs)),
      padded_(outputs_ <= 16 ? 16 : outputs_ <= 32 ? 32 : 64) {
    params_.assign(b3() + size_t(padded_), 0.0f);
    SplitMix64 rng(seed ^ 0x6e65656e6574ull);
    auto fill = [&](size_t at, int fanIn, size_t count) {
        float bound = std::sqrt(6.0f / float(fanIn));  // He uniform
        for (size_t i = 0; i < count; ++i) params_[at + i] = (2.0f * rng.uniform() - 1.0f) * bound;
    };
    const size_t b1 = size_t(kIn) * kHid, w2 = b1 + kHid, b2 = w2 + size_t(kHid) * kHid;
    fill(0, kIn, size_t(kIn) * kHid);
    fill(w2, kHid, size_t(kHid) * kHid);
    for (int i = 0; i < kHid; ++i) fill(w3() + size_t(i) * size_t(padded_), kHid, size_t(outputs_));
    for (int i = 0; i < kHid; ++i) params_[b1 + size_t(i)] = params_[b2 + size_t(i)] = 0.01f;
    // Output layer starts small: an almost uniform distribution until the first contributions arrive.
    // Padding columns stay zero: their gradient is zero.
    for (size_t i = 0; i < size_t(kHid) * size_t(padded_); ++i) params_[w3() + i] *= 0.1f;
}

void PaddedMlp::forward(const float* x, Activations& a) const { forwardLayers(params_.data(), padded_, x, a); }

void PaddedMlp::backward(const float* x, const Activations& a, const float* dLogits, float* grad) const {
    backwardLayers(params_.data(), padded_, x, a, dLogits, grad);
}

std::vector<float> PaddedMlp::toRowMajor(const std::vector<float>& padded) const {
    std::vector<float> out;
    const size_t b1 = size_t(kIn) * kHid, w2 = b1 + kHid, b2 = w2 + size_t(kHid) * kHid;
    auto layer = [&](size_t w, size_t b, int in, int stride, int outs) {
        for (int o = 0; o < outs; ++o)
            for (int i = 0; i < in; ++i) out.push_back(padded[w + size_t(i) * size_t(stride) + size_t(o)]);
        for (int o = 0; o < outs; ++o) out.push_back(padded[b + size_t(o)]);
    };
    layer(0, b1, kIn, kHid, kHid);
    layer(w2, b2, kHid, kHid, kHid);
    layer(w3(), b3(), kHid, padded_, outputs_);
    return out;
}

}  // namespace nrad
