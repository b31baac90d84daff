// The lockstep training step (mlp_lockstep.h) over an 8-lane type, included once per instruction set
// (mlp_lockstep.cpp: plain lanes with std::fma; mlp_lockstep_avx2.cpp: AVX2 with FMA), each in its own namespace
// NRAD_LOCKSTEP_KERNELS and compiled with -ffp-contract=off: the fused multiply-adds are the ones written as fma(),
// nothing else fuses, so every instruction set gives the same bits.
#pragma once

#include <algorithm>
#include <cmath>
#include <cstddef>

#if defined(__AVX2__) && defined(__FMA__)
#include <immintrin.h>
#endif

#include "baker/nn/mlp_lockstep.h"

namespace nrad {
namespace NRAD_LOCKSTEP_KERNELS {
constexpr int W8 = kLockstepLanes;
static_assert(W8 == 8, "the lane types below hold eight floats");

#if defined(__AVX2__) && defined(__FMA__)
struct V8 {
    __m256 v;
};
inline V8 splat(float x) { return {_mm256_set1_ps(x)}; }
inline V8 load(const float* p) { return {_mm256_loadu_ps(p)}; }
inline void store(float* p, V8 a) { _mm256_storeu_ps(p, a.v); }
inline V8 operator+(V8 a, V8 b) { return {_mm256_add_ps(a.v, b.v)}; }
inline V8 operator-(V8 a, V8 b) { return {_mm256_sub_ps(a.v, b.v)}; }
inline V8 operator*(V8 a, V8 b) { return {_mm256_mul_ps(a.v, b.v)}; }
inline V8 operator/(V8 a, V8 b) { return {_mm256_div_ps(a.v, b.v)}; }
inline V8 sqrt(V8 a) { return {_mm256_sqrt_ps(a.v)}; }
inline V8 fma(V8 a, V8 b, V8 c) { return {_mm256_fmadd_ps(a.v, b.v, c.v)}; }  // a b + c, one rounding
// p > 0 ? v : 0 (NaN in p gives 0).
inline V8 whereAboveZero(V8 p, V8 v) { return {_mm256_and_ps(v.v, _mm256_cmp_ps(p.v, _mm256_setzero_ps(), _CMP_GT_OQ))}; }
// a < b ? v : 0.
inline V8 whereLess(V8 a, V8 b, V8 v) { return {_mm256_and_ps(v.v, _mm256_cmp_ps(a.v, b.v, _CMP_LT_OQ))}; }
// m > 0 ? a : b.
inline V8 selectAboveZero(V8 m, V8 a, V8 b) { return {_mm256_blendv_ps(b.v, a.v, _mm256_cmp_ps(m.v, _mm256_setzero_ps(), _CMP_GT_OQ))}; }

// out[q] = lane j of out[q] = rows[j][q] for q < kPackedFloats: two 8 x 8 transposes.
inline void transposeRows(const float* const rows[W8], float* out) {
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
        float* o = out + size_t(8 * half) * W8;
        for (int q = 0; q < 4; ++q) {
            _mm256_storeu_ps(o + size_t(q) * W8, _mm256_permute2f128_ps(u[q], u[q + 4], 0x20));
            _mm256_storeu_ps(o + size_t(q + 4) * W8, _mm256_permute2f128_ps(u[q], u[q + 4], 0x31));
        }
    }
}
#else
struct V8 {
    float f[W8];
};
inline V8 splat(float x) {
    V8 r;
    for (float& f : r.f) f = x;
    return r;
}
inline V8 load(const float* p) {
    V8 r;
    for (int j = 0; j < W8; ++j) r.f[j] = p[j];
    return r;
}
inline void store(float* p, V8 a) {
    for (int j = 0; j < W8; ++j) p[j] = a.f[j];
}
#define NRAD_LOCKSTEP_LANEWISE(op)                              \
    inline V8 operator op(V8 a, V8 b) {                         \
        V8 r;                                                   \
        for (int j = 0; j < W8; ++j) r.f[j] = a.f[j] op b.f[j]; \
        return r;                                               \
    }
NRAD_LOCKSTEP_LANEWISE(+)
NRAD_LOCKSTEP_LANEWISE(-)
NRAD_LOCKSTEP_LANEWISE(*)
NRAD_LOCKSTEP_LANEWISE(/)
#undef NRAD_LOCKSTEP_LANEWISE
inline V8 sqrt(V8 a) {
    V8 r;
    for (int j = 0; j < W8; ++j) r.f[j] = std::sqrt(a.f[j]);
    return r;
}
inline V8 fma(V8 a, V8 b, V8 c) {
    V8 r;
    for (int j = 0; j < W8; ++j) r.f[j] = std::fma(a.f[j], b.f[j], c.f[j]);
    return r;
}
inline V8 whereAboveZero(V8 p, V8 v) {
    V8 r;
    for (int j = 0; j < W8; ++j) r.f[j] = p.f[j] > 0.0f ? v.f[j] : 0.0f;
    return r;
}
inline V8 whereLess(V8 a, V8 b, V8 v) {
    V8 r;
    for (int j = 0; j < W8; ++j) r.f[j] = a.f[j] < b.f[j] ? v.f[j] : 0.0f;
    return r;
}
inline V8 selectAboveZero(V8 m, V8 a, V8 b) {
    V8 r;
    for (int j = 0; j < W8; ++j) r.f[j] = m.f[j] > 0.0f ? a.f[j] : b.f[j];
    return r;
}
inline void transposeRows(const float* const rows[W8], float* out) {
    for (int q = 0; q < kPackedFloats; ++q)
        for (int j = 0; j < W8; ++j) out[size_t(q) * W8 + size_t(j)] = rows[j][q];
}
#endif

namespace {

// The width of layer l (0: the inputs) and the stride of its activations per sample (layer 0: the packed rows).
inline int width(const NetworkShape& s, size_t l) { return l == 0 ? s.inputs : l <= s.hidden.size() ? s.hidden[l - 1] : s.outputs; }
inline size_t stride(const NetworkShape& s, size_t l) { return l == 0 ? size_t(kPackedFloats) : size_t(width(s, l)); }

// The gradient of an OB x IB block of a layer's weights, W[o0 + a][i0 + b]: each a sum over the samples in
// order, fused, from zero.
template <int OB, int IB>
inline void gradBlock(const float* D, size_t dStride, const float* A, size_t aStride, int n, int o0, int i0, int in, float* gW) {
    V8 acc[OB][IB];
    for (int a = 0; a < OB; ++a)
        for (int b = 0; b < IB; ++b) acc[a][b] = splat(0.0f);
    for (int k = 0; k < n; ++k) {
        V8 d[OB];
        for (int a = 0; a < OB; ++a) d[a] = load(D + (size_t(k) * dStride + size_t(o0 + a)) * W8);
        for (int b = 0; b < IB; ++b) {
            const V8 x = load(A + (size_t(k) * aStride + size_t(i0 + b)) * W8);
            for (int a = 0; a < OB; ++a) acc[a][b] = fma(d[a], x, acc[a][b]);
        }
    }
    for (int a = 0; a < OB; ++a)
        for (int b = 0; b < IB; ++b) store(gW + (size_t(o0 + a) * size_t(in) + size_t(i0 + b)) * W8, acc[a][b]);
}

template <int OB>
inline void gradRows(const float* D, size_t dStride, const float* A, size_t aStride, int n, int o0, int in, float* gW) {
    int i0 = 0;
    for (; i0 + 4 <= in; i0 += 4) gradBlock<OB, 4>(D, dStride, A, aStride, n, o0, i0, in, gW);
    switch (in - i0) {
        case 3: gradBlock<OB, 3>(D, dStride, A, aStride, n, o0, i0, in, gW); break;
        case 2: gradBlock<OB, 2>(D, dStride, A, aStride, n, o0, i0, in, gW); break;
        case 1: gradBlock<OB, 1>(D, dStride, A, aStride, n, o0, i0, in, gW); break;
        default: break;
    }
}

void prepare(const NetworkShape& s, LockstepWorkspace& ws) {
    const size_t layers = s.hidden.size() + 1;
    if (ws.at.size() == layers + 2) return;
    constexpr size_t B = MlpBatchWorkspace::kMaxBatch;
    ws.at.assign(1, 0);
    for (size_t l = 0; l <= layers; ++l) ws.at.push_back(ws.at.back() + B * stride(s, l) * W8);
    // One buffer: the activations, then the deltas half a page further than a whole number of pages, so that a
    // delta stored and the activation loaded at the same index never share their address's low 12 bits (4K
    // aliasing: docs/design.md), then the gradient.
    const size_t size = ws.at.back(), deltasAt = (size + 1023) / 1024 * 1024 + 512;
    ws.buffer.assign(deltasAt + size + s.parameterCount() * W8, 0.0f);
    ws.values = ws.buffer.data();
    ws.deltas = ws.values + deltasAt;
    ws.grad = ws.deltas + size;
}

}  // namespace

// What the phases of a step share: the networks, the workspace, the most samples of any lane (n) and that
// rounded up to four (n4), and the lanes' per-step values.
struct Step {
    Step(LockstepNetworks& networks, LockstepWorkspace& workspace)
        : nets(networks), ws(workspace), s(networks.shape), L(s.hidden.size() + 1), values(ws.values), deltas(ws.deltas) {}
    LockstepNetworks& nets;
    LockstepWorkspace& ws;
    const NetworkShape& s;
    const size_t L;  // layers with weights
    float* values;  // every layer's activations (layer 0: the samples)
    float* deltas;
    int n = 0, n4 = 0;
    float countLanes[W8] = {}, invLanes[W8] = {}, rateLanes[W8] = {}, decayLanes[W8] = {}, epsLanes[W8] = {};

    void gatherSamples(const LockstepLane lanes[kLockstepLanes]);
    void forwardPass();
    void lossGradient(LossKind loss);
    void backpropagate();
    void sumGradient();
    void adamStep();
};

inline void Step::gatherSamples(const LockstepLane lanes[kLockstepLanes]) {
    // The samples, lane by lane (a resting lane, or one past its count, reads zeros: finite, and its gradient is
    // masked to zero below).
    static const float zeros[kPackedFloats] = {};
    static const float* const zeroRows[W8] = {zeros, zeros, zeros, zeros, zeros, zeros, zeros, zeros};
    for (int k = 0; k < n; ++k) {
        const float* rows[W8];
        for (int j = 0; j < W8; ++j) rows[j] = k < lanes[j].count ? lanes[j].rows[k] : zeros;
        transposeRows(rows, values + ws.at[0] + size_t(k) * kPackedFloats * W8);
    }
    for (int k = n; k < n4; ++k) transposeRows(zeroRows, values + ws.at[0] + size_t(k) * kPackedFloats * W8);
}

inline void Step::forwardPass() {
    // Forward: each unit's sum from its bias up in input order; ReLU on the hidden layers. Four samples at a time,
    // each weight loaded once for them (samples past n are the zero rows: finite, never in a gradient).
    for (int k0 = 0; k0 < n4; k0 += 4)
        for (size_t l = 0; l < L; ++l) {
            const int in = width(s, l), out = width(s, l + 1);
            const size_t as = stride(s, l) * W8, zs = size_t(out) * W8;
            const float* Wl = nets.params.data() + nets.offsets[l] * W8;
            const float* bl = Wl + size_t(out) * size_t(in) * W8;
            const float* a = values + ws.at[l] + size_t(k0) * as;
            float* z = values + ws.at[l + 1] + size_t(k0) * zs;
            for (int o = 0; o < out; ++o) {
                V8 acc[4];
                for (int q = 0; q < 4; ++q) acc[q] = load(bl + size_t(o) * W8);
                const float* w = Wl + size_t(o) * size_t(in) * W8;
                for (int i = 0; i < in; ++i) {
                    const V8 wi = load(w + size_t(i) * W8);
                    for (int q = 0; q < 4; ++q) acc[q] = fma(wi, load(a + size_t(q) * as + size_t(i) * W8), acc[q]);
                }
                for (int q = 0; q < 4; ++q) store(z + size_t(q) * zs + size_t(o) * W8, l + 1 == L ? acc[q] : whereAboveZero(acc[q], acc[q]));
            }
        }
}

inline void Step::lossGradient(LossKind loss) {
    // The loss's gradient at the outputs (loss.cpp's regressionGradient, lane by lane), zero past a lane's count.
    const V8 count = load(countLanes);
    for (int k = 0; k < n4; ++k) {
        const float* row = values + ws.at[0] + size_t(k) * kPackedFloats * W8;
        const float* y = values + ws.at[L] + size_t(k) * 3 * W8;
        float* dy = deltas + ws.at[L] + size_t(k) * 3 * W8;
        V8 w = splat(1.0f);
        if (loss == LossKind::RelativeL2) {
            const V8 y0 = load(y), y1 = load(y + W8), y2 = load(y + 2 * W8);
            const V8 lum = splat(0.2126f) * whereAboveZero(y0, y0) + splat(0.7152f) * whereAboveZero(y1, y1) +
                           splat(0.0722f) * whereAboveZero(y2, y2);
            w = splat(1.0f) / (lum * lum + splat(0.01f));
        }
        const V8 kk = splat(float(k));
        for (int c = 0; c < 3; ++c) {
            const V8 g = splat(2.0f) * w * load(row + size_t(kPackedWeight + c) * W8) *
                         (load(y + size_t(c) * W8) - load(row + size_t(kPackedTarget + c) * W8));
            store(dy + size_t(c) * W8, whereLess(kk, count, g));
        }
    }
}

inline void Step::backpropagate() {
    // Backpropagation: each hidden unit's delta its sum over the next layer's units in order, from zero, where the
    // unit is active; four samples at a time.
    for (int k0 = 0; k0 < n4; k0 += 4)
        for (size_t l = L - 1; l >= 1; --l) {
            const int in = width(s, l), out = width(s, l + 1);
            const float* Wl = nets.params.data() + nets.offsets[l] * W8;
            const size_t ns = size_t(out) * W8, bs = size_t(in) * W8;
            const float* next = deltas + ws.at[l + 1] + size_t(k0) * ns;
            const float* a = values + ws.at[l] + size_t(k0) * bs;
            float* back = deltas + ws.at[l] + size_t(k0) * bs;
            for (int i = 0; i < in; ++i) {
                V8 acc[4] = {splat(0.0f), splat(0.0f), splat(0.0f), splat(0.0f)};
                for (int o = 0; o < out; ++o) {
                    const V8 w = load(Wl + (size_t(o) * size_t(in) + size_t(i)) * W8);
                    for (int q = 0; q < 4; ++q) acc[q] = fma(w, load(next + size_t(q) * ns + size_t(o) * W8), acc[q]);
                }
                for (int q = 0; q < 4; ++q)
                    store(back + size_t(q) * bs + size_t(i) * W8, whereAboveZero(load(a + size_t(q) * bs + size_t(i) * W8), acc[q]));
            }
        }
}

inline void Step::sumGradient() {
    // The gradient, summed over the samples in order.
    float* grad = ws.grad;
    for (size_t l = 0; l < L; ++l) {
        const int in = width(s, l), out = width(s, l + 1);
        const float* D = deltas + ws.at[l + 1];
        const float* A = values + ws.at[l];
        float* gW = grad + nets.offsets[l] * W8;
        int o0 = 0;
        for (; o0 + 3 <= out; o0 += 3) gradRows<3>(D, size_t(out), A, stride(s, l), n, o0, in, gW);
        if (out - o0 == 2) gradRows<2>(D, size_t(out), A, stride(s, l), n, o0, in, gW);
        if (out - o0 == 1) gradRows<1>(D, size_t(out), A, stride(s, l), n, o0, in, gW);
        float* gb = gW + size_t(out) * size_t(in) * W8;
        for (int o = 0; o < out; ++o) {
            V8 acc = splat(0.0f);
            for (int k = 0; k < n; ++k) acc = acc + load(D + (size_t(k) * size_t(out) + size_t(o)) * W8);
            store(gb + size_t(o) * W8, acc);
        }
    }
}

inline void Step::adamStep() {
    const float* grad = ws.grad;
    // The mean gradient, the L2 penalty (not on the output biases), Adam (the bias corrections folded into the
    // rate and epsilon, as Kingma and Ba's Sec. 2 arranges it: one square root and one division a parameter);
    // resting lanes keep everything.
    const V8 inv = load(invLanes), rate = load(rateLanes), decay = load(decayLanes), epsT = load(epsLanes);
    const V8 count = load(countLanes);
    const V8 b1 = splat(kAdamBeta1), b2 = splat(kAdamBeta2);
    const V8 nb1 = splat(1.0f - kAdamBeta1), nb2 = splat(1.0f - kAdamBeta2);
    const size_t P = nets.parameterCount(), penalised = P - size_t(s.outputs);
    float* p = nets.params.data();
    float* m = nets.m.data();
    float* v = nets.v.data();
    for (size_t q = 0; q < P; ++q) {
        const size_t at = q * W8;
        const V8 pq = load(p + at);
        V8 g = load(grad + at) * inv;
        if (q < penalised) g = g + whereAboveZero(decay, decay * pq);
        const V8 mq = b1 * load(m + at) + nb1 * g;
        const V8 vq = b2 * load(v + at) + nb2 * g * g;
        const V8 next = pq - rate * mq / (sqrt(vq) + epsT);
        store(m + at, selectAboveZero(count, mq, load(m + at)));
        store(v + at, selectAboveZero(count, vq, load(v + at)));
        store(p + at, selectAboveZero(count, next, pq));
    }
}

void trainStep(LockstepNetworks& nets, const LockstepLane lanes[kLockstepLanes], LossKind loss, LockstepWorkspace& ws) {
    prepare(nets.shape, ws);
    Step st(nets, ws);
    for (int j = 0; j < W8; ++j) {
        const LockstepLane& lane = lanes[j];
        st.n = std::max(st.n, lane.count);
        st.countLanes[j] = float(lane.count);
        st.invLanes[j] = lane.count > 0 ? 1.0f / float(lane.count) : 0.0f;
        const AdamRates r = adamRates(lane.learningRate, lane.c1, lane.c2);
        st.rateLanes[j] = r.rate;
        st.epsLanes[j] = r.epsilon;
        st.decayLanes[j] = lane.weightDecay;
    }
    if (st.n == 0) return;
    st.n4 = (st.n + 3) / 4 * 4;
    st.gatherSamples(lanes);
    st.forwardPass();
    st.lossGradient(loss);
    st.backpropagate();
    st.sumGradient();
    st.adamStep();
}

}  // namespace NRAD_LOCKSTEP_KERNELS
}  // namespace nrad
