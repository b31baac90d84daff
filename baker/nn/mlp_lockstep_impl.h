// The lockstep training step (mlp_lockstep.h) over a lane type V of V::W lanes, included once per instruction set,
// each in its own namespace NRAD_LOCKSTEP_KERNELS and compiled with -ffp-contract=off: the fused multiply-adds are
// the ones written as fma(), nothing else fuses, so every instruction set gives the same bits.
//
// A lane type V (defined by the file that includes this one, in the same namespace) has W, kGradInputs (the widest
// block of weights' gradients it keeps in registers: 4, or 8 with 32 registers), V::splat(x),
// V::load(p), V::store(p, v), V::transposeRows(rows, out) (out[q W + j] = rows[j][q] for q < kPackedFloats), and
// + - * /, sqrt, fma (one rounding), whereAboveZero(p, v) (p > 0 ? v : 0, NaN gives 0), whereLess(a, b, v)
// (a < b ? v : 0) and selectAboveZero(m, a, b) (m > 0 ? a : b), lane by lane.
#pragma once

#include <algorithm>
#include <cmath>
#include <cstddef>

#include "baker/nn/mlp_lockstep.h"

namespace nrad {
namespace NRAD_LOCKSTEP_KERNELS {

namespace {

// Samples per pass of the forward and backward loops: eight independent chains of multiply-adds, as many as two FMA
// pipes of four cycles' latency keep busy, and few enough accumulators for AVX2's sixteen registers (train_bench
// measured no difference from four, on AVX2 or AVX-512).
constexpr int kSampleBlock = 8;

// The width of layer l (0: the inputs) and the stride of its activations per sample (layer 0: the packed rows).
inline int width(const NetworkShape& s, size_t l) { return l == 0 ? s.inputs : l <= s.hidden.size() ? s.hidden[l - 1] : s.outputs; }
inline size_t stride(const NetworkShape& s, size_t l) { return l == 0 ? size_t(kPackedFloats) : size_t(width(s, l)); }

// The gradient of an OB x IB block of a layer's weights, W[o0 + a][i0 + b]: each a sum over the samples in
// order, fused, from zero (the blocks' shape only decides which sums run together: any shape gives the same bits).
// With Bias, the block also sums the rows' bias gradients, D[o0 + a] over the samples in order from zero (fma(d, 1,
// s) rounds as s + d does), into gB.
template <class V, int OB, int IB, bool Bias = false>
inline void gradBlock(const float* D, size_t dStride, const float* A, size_t aStride, int n, int o0, int i0, int in, float* gW, float* gB) {
    constexpr size_t W = size_t(V::W);
    V acc[OB][IB], bias[OB];
    for (int a = 0; a < OB; ++a) {
        bias[a] = V::splat(0.0f);
        for (int b = 0; b < IB; ++b) acc[a][b] = V::splat(0.0f);
    }
    for (int k = 0; k < n; ++k) {
        V d[OB];
        for (int a = 0; a < OB; ++a) d[a] = V::load(D + (size_t(k) * dStride + size_t(o0 + a)) * W);
        if constexpr (Bias)
            for (int a = 0; a < OB; ++a) bias[a] = bias[a] + d[a];
        for (int b = 0; b < IB; ++b) {
            const V x = V::load(A + (size_t(k) * aStride + size_t(i0 + b)) * W);
            for (int a = 0; a < OB; ++a) acc[a][b] = fma(d[a], x, acc[a][b]);
        }
    }
    for (int a = 0; a < OB; ++a)
        for (int b = 0; b < IB; ++b) V::store(gW + (size_t(o0 + a) * size_t(in) + size_t(i0 + b)) * W, acc[a][b]);
    if constexpr (Bias)
        for (int a = 0; a < OB; ++a) V::store(gB + size_t(o0 + a) * W, bias[a]);
}

// Rows o0 .. o0 + OB - 1 of a layer's weight gradient (in inputs, IN where known when compiling, else 0) and their
// bias gradients (gB), the biases summed with the last block (the one with the fewest accumulators).
template <class V, int OB, int IN = 0>
inline void gradRows(const float* D, size_t dStride, const float* A, size_t aStride, int n, int o0, int inAtRunTime, float* gW, float* gB) {
    const int in = IN ? IN : inAtRunTime;
    int i0 = 0;
    if constexpr (V::kGradInputs == 8)  // 24 accumulators
        for (; i0 + 8 < in; i0 += 8) gradBlock<V, OB, 8>(D, dStride, A, aStride, n, o0, i0, in, gW, gB);
    for (; i0 + 4 < in; i0 += 4) gradBlock<V, OB, 4>(D, dStride, A, aStride, n, o0, i0, in, gW, gB);
    switch (in - i0) {
        case 4: gradBlock<V, OB, 4, true>(D, dStride, A, aStride, n, o0, i0, in, gW, gB); break;
        case 3: gradBlock<V, OB, 3, true>(D, dStride, A, aStride, n, o0, i0, in, gW, gB); break;
        case 2: gradBlock<V, OB, 2, true>(D, dStride, A, aStride, n, o0, i0, in, gW, gB); break;
        case 1: gradBlock<V, OB, 1, true>(D, dStride, A, aStride, n, o0, i0, in, gW, gB); break;
        default: break;
    }
}

void prepare(const NetworkShape& s, int lanes, LockstepWorkspace& ws) {
    const size_t layers = s.hidden.size() + 1;
    if (ws.at.size() == layers + 2 && ws.lanes == lanes) return;
    ws.lanes = lanes;
    const size_t W = size_t(lanes);
    constexpr size_t B = MlpBatchWorkspace::kMaxBatch;
    ws.at.assign(1, 0);
    for (size_t l = 0; l <= layers; ++l) ws.at.push_back(ws.at.back() + B * stride(s, l) * W);
    // One buffer: the activations, then the deltas half a page further than a whole number of pages, so that a
    // delta stored and the activation loaded at the same index never share their address's low 12 bits (4K
    // aliasing: docs/design.md), then the gradient.
    const size_t size = ws.at.back(), deltasAt = (size + 1023) / 1024 * 1024 + 512;
    ws.buffer.assign(deltasAt + size + s.parameterCount() * W, 0.0f);
    ws.values = ws.buffer.data();
    ws.deltas = ws.values + deltasAt;
    ws.grad = ws.deltas + size;
}

}  // namespace

// What the phases of a step share: the networks, the workspace, the most samples of any lane (n) and that
// rounded up to a whole number of sample blocks (nBlocks), and the lanes' per-step values.
template <class V>
struct Step {
    static constexpr int W = V::W;
    Step(LockstepNetworks& networks, LockstepWorkspace& workspace)
        : nets(networks), ws(workspace), s(networks.shape), L(s.hidden.size() + 1), values(ws.values), deltas(ws.deltas) {}
    LockstepNetworks& nets;
    LockstepWorkspace& ws;
    const NetworkShape& s;
    const size_t L;  // layers with weights
    float* values;  // every layer's activations (layer 0: the samples)
    float* deltas;
    int n = 0, nBlocks = 0;
    alignas(64) float countLanes[W] = {}, invLanes[W] = {}, rateLanes[W] = {}, decayLanes[W] = {}, epsLanes[W] = {};

    void gatherSamples(const LockstepLane* lanes);
    void forwardPass();
    void lossGradient(LossKind loss);
    void backpropagate();
    void sumGradient();
    void adamStep();
};

template <class V>
inline void Step<V>::gatherSamples(const LockstepLane* lanes) {
    // The samples, lane by lane (a resting lane, or one past its count, reads zeros: finite, and its gradient is
    // masked to zero below).
    static const float zeros[kPackedFloats] = {};
    const float* zeroRows[W];
    for (const float*& r : zeroRows) r = zeros;
    int full = n;  // the samples every lane has
    for (int j = 0; j < W; ++j) full = std::min(full, lanes[j].count);
    for (int k = 0; k < n; ++k) {
        const float* rows[W];
        if (k < full)
            for (int j = 0; j < W; ++j) rows[j] = lanes[j].rows[k];
        else
            for (int j = 0; j < W; ++j) rows[j] = k < lanes[j].count ? lanes[j].rows[k] : zeros;
        V::transposeRows(rows, values + ws.at[0] + size_t(k) * kPackedFloats * W);
    }
    for (int k = n; k < nBlocks; ++k) V::transposeRows(zeroRows, values + ws.at[0] + size_t(k) * kPackedFloats * W);
}

// One layer's forward pass for kSampleBlock samples: each unit's sum from its bias up in input order; ReLU where
// `relu`. IN and OUT are the layer's widths where known when compiling (the default 9-9-3 network's layers: the
// loops unrolled), else 0 and the widths at run time (the same operations in the same order either way).
template <class V, int IN, int OUT>
inline void forwardLayer(const float* Wl, const float* a, size_t as, float* z, int inAtRunTime, int outAtRunTime, bool relu) {
    constexpr size_t W = size_t(V::W);
    const int in = IN ? IN : inAtRunTime, out = OUT ? OUT : outAtRunTime;
    const size_t zs = size_t(out) * W;
    const float* bl = Wl + size_t(out) * size_t(in) * W;
    for (int o = 0; o < out; ++o) {
        V acc[kSampleBlock];
        for (int q = 0; q < kSampleBlock; ++q) acc[q] = V::load(bl + size_t(o) * W);
        const float* w = Wl + size_t(o) * size_t(in) * W;
        for (int i = 0; i < in; ++i) {
            const V wi = V::load(w + size_t(i) * W);
            for (int q = 0; q < kSampleBlock; ++q) acc[q] = fma(wi, V::load(a + size_t(q) * as + size_t(i) * W), acc[q]);
        }
        for (int q = 0; q < kSampleBlock; ++q) V::store(z + size_t(q) * zs + size_t(o) * W, relu ? whereAboveZero(acc[q], acc[q]) : acc[q]);
    }
}

template <class V>
inline void Step<V>::forwardPass() {
    // Forward, kSampleBlock samples at a time, each weight loaded once for them and their sums independent chains
    // (samples past n are the zero rows: finite, never in a gradient).
    for (int k0 = 0; k0 < nBlocks; k0 += kSampleBlock)
        for (size_t l = 0; l < L; ++l) {
            const int in = width(s, l), out = width(s, l + 1);
            const size_t as = stride(s, l) * W;
            const float* Wl = nets.params.data() + nets.offsets[l] * W;
            const float* a = values + ws.at[l] + size_t(k0) * as;
            float* z = values + ws.at[l + 1] + size_t(k0) * size_t(out) * W;
            const bool relu = l + 1 < L;
            if (in == 9 && out == 9) forwardLayer<V, 9, 9>(Wl, a, as, z, in, out, relu);
            else if (in == 9 && out == 3) forwardLayer<V, 9, 3>(Wl, a, as, z, in, out, relu);
            else forwardLayer<V, 0, 0>(Wl, a, as, z, in, out, relu);
        }
}

template <class V>
inline void Step<V>::lossGradient(LossKind loss) {
    // The loss's gradient at the outputs (loss.cpp's regressionGradient, lane by lane), zero past a lane's count.
    const V count = V::load(countLanes);
    for (int k = 0; k < nBlocks; ++k) {
        const float* row = values + ws.at[0] + size_t(k) * kPackedFloats * W;
        const float* y = values + ws.at[L] + size_t(k) * 3 * W;
        float* dy = deltas + ws.at[L] + size_t(k) * 3 * W;
        if (loss == LossKind::SymmetricRelativeExp) {  // the exponential's lanes through the plain loss, one by one
            for (int j = 0; j < W; ++j) {
                const float yj[3] = {y[j], y[W + j], y[2 * W + j]};
                const float tj[3] = {row[size_t(kPackedTarget) * W + j], row[size_t(kPackedTarget + 1) * W + j],
                                     row[size_t(kPackedTarget + 2) * W + j]};
                const float wj[3] = {row[size_t(kPackedWeight) * W + j], row[size_t(kPackedWeight + 1) * W + j],
                                     row[size_t(kPackedWeight + 2) * W + j]};
                float g[3];
                regressionGradient(loss, yj, tj, wj, g);
                for (int c = 0; c < 3; ++c) dy[size_t(c) * W + j] = float(k) < countLanes[j] ? g[c] : 0.0f;
            }
            continue;
        }
        V w = V::splat(1.0f);
        if (loss == LossKind::RelativeL2) {
            const V y0 = V::load(y), y1 = V::load(y + W), y2 = V::load(y + 2 * W);
            const V lum = V::splat(0.2126f) * whereAboveZero(y0, y0) + V::splat(0.7152f) * whereAboveZero(y1, y1) +
                           V::splat(0.0722f) * whereAboveZero(y2, y2);
            w = V::splat(1.0f) / (lum * lum + V::splat(0.01f));
        } else if (loss == LossKind::SymmetricRelativeL2) {
            const V y0 = V::load(y), y1 = V::load(y + W), y2 = V::load(y + 2 * W);
            const V lum = V::splat(0.2126f) * whereAboveZero(y0, y0) + V::splat(0.7152f) * whereAboveZero(y1, y1) +
                           V::splat(0.0722f) * whereAboveZero(y2, y2);
            const V t0 = V::load(row + size_t(kPackedTarget) * W), t1 = V::load(row + size_t(kPackedTarget + 1) * W),
                    t2 = V::load(row + size_t(kPackedTarget + 2) * W);
            const V tl = V::splat(0.2126f) * whereAboveZero(t0, t0) + V::splat(0.7152f) * whereAboveZero(t1, t1) +
                          V::splat(0.0722f) * whereAboveZero(t2, t2);
            w = V::splat(1.0f) / (V::splat(0.5f) * (lum * lum + tl * tl) + V::splat(0.01f));
        }
        const V kk = V::splat(float(k));
        for (int c = 0; c < 3; ++c) {
            const V g = V::splat(2.0f) * w * V::load(row + size_t(kPackedWeight + c) * W) *
                         (V::load(y + size_t(c) * W) - V::load(row + size_t(kPackedTarget + c) * W));
            V::store(dy + size_t(c) * W, whereLess(kk, count, g));
        }
    }
}

// One hidden layer's deltas for kSampleBlock samples: each unit's sum over the next layer's units in order, from
// zero, where the unit is active. IN, OUT: as forwardLayer's.
template <class V, int IN, int OUT>
inline void backLayer(const float* Wl, const float* next, const float* a, float* back, int inAtRunTime, int outAtRunTime) {
    constexpr size_t W = size_t(V::W);
    const int in = IN ? IN : inAtRunTime, out = OUT ? OUT : outAtRunTime;
    const size_t ns = size_t(out) * W, bs = size_t(in) * W;
    for (int i = 0; i < in; ++i) {
        V acc[kSampleBlock];
        for (V& x : acc) x = V::splat(0.0f);
        for (int o = 0; o < out; ++o) {
            const V w = V::load(Wl + (size_t(o) * size_t(in) + size_t(i)) * W);
            for (int q = 0; q < kSampleBlock; ++q) acc[q] = fma(w, V::load(next + size_t(q) * ns + size_t(o) * W), acc[q]);
        }
        for (int q = 0; q < kSampleBlock; ++q)
            V::store(back + size_t(q) * bs + size_t(i) * W, whereAboveZero(V::load(a + size_t(q) * bs + size_t(i) * W), acc[q]));
    }
}

template <class V>
inline void Step<V>::backpropagate() {
    // Backpropagation, kSampleBlock samples at a time.
    for (int k0 = 0; k0 < nBlocks; k0 += kSampleBlock)
        for (size_t l = L - 1; l >= 1; --l) {
            const int in = width(s, l), out = width(s, l + 1);
            const float* Wl = nets.params.data() + nets.offsets[l] * W;
            const float* next = deltas + ws.at[l + 1] + size_t(k0) * size_t(out) * W;
            const float* a = values + ws.at[l] + size_t(k0) * size_t(in) * W;
            float* back = deltas + ws.at[l] + size_t(k0) * size_t(in) * W;
            if (in == 9 && out == 3) backLayer<V, 9, 3>(Wl, next, a, back, in, out);
            else backLayer<V, 0, 0>(Wl, next, a, back, in, out);
        }
}

template <class V>
inline void Step<V>::sumGradient() {
    // The gradient, summed over the samples in order.
    float* grad = ws.grad;
    for (size_t l = 0; l < L; ++l) {
        const int in = width(s, l), out = width(s, l + 1);
        const float* D = deltas + ws.at[l + 1];
        const float* A = values + ws.at[l];
        float* gW = grad + nets.offsets[l] * W;
        float* gb = gW + size_t(out) * size_t(in) * W;
        int o0 = 0;
        if (in == 9)
            for (; o0 + 3 <= out; o0 += 3) gradRows<V, 3, 9>(D, size_t(out), A, stride(s, l), n, o0, in, gW, gb);
        for (; o0 + 3 <= out; o0 += 3) gradRows<V, 3>(D, size_t(out), A, stride(s, l), n, o0, in, gW, gb);
        if (out - o0 == 2) gradRows<V, 2>(D, size_t(out), A, stride(s, l), n, o0, in, gW, gb);
        if (out - o0 == 1) gradRows<V, 1>(D, size_t(out), A, stride(s, l), n, o0, in, gW, gb);
    }
}

template <class V>
inline void Step<V>::adamStep() {
    const float* grad = ws.grad;
    // The mean gradient, the L2 penalty (not on the output biases), Adam (the bias corrections folded into the
    // rate and epsilon, as Kingma and Ba's Sec. 2 arranges it: one square root and one division a parameter);
    // resting lanes keep everything.
    const V inv = V::load(invLanes), rate = V::load(rateLanes), decay = V::load(decayLanes), epsT = V::load(epsLanes);
    const V count = V::load(countLanes);
    const V b1 = V::splat(kAdamBeta1), b2 = V::splat(kAdamBeta2);
    const V nb1 = V::splat(1.0f - kAdamBeta1), nb2 = V::splat(1.0f - kAdamBeta2);
    const size_t P = nets.parameterCount(), penalised = P - size_t(s.outputs);
    float* p = nets.params.data();
    float* m = nets.m.data();
    float* v = nets.v.data();
    for (size_t q = 0; q < P; ++q) {
        const size_t at = q * W;
        const V pq = V::load(p + at);
        V g = V::load(grad + at) * inv;
        if (q < penalised) g = g + whereAboveZero(decay, decay * pq);
        const V mq = b1 * V::load(m + at) + nb1 * g;
        const V vq = b2 * V::load(v + at) + nb2 * g * g;
        const V next = pq - rate * mq / (sqrt(vq) + epsT);
        V::store(m + at, selectAboveZero(count, mq, V::load(m + at)));
        V::store(v + at, selectAboveZero(count, vq, V::load(v + at)));
        V::store(p + at, selectAboveZero(count, next, pq));
    }
}

// One step of nets (nets.lanes == V::W) with lane type V.
template <class V>
void stepWith(LockstepNetworks& nets, const LockstepLane* lanes, LossKind loss, LockstepWorkspace& ws) {
    prepare(nets.shape, V::W, ws);
    Step<V> st(nets, ws);
    for (int j = 0; j < V::W; ++j) {
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
    st.nBlocks = (st.n + kSampleBlock - 1) / kSampleBlock * kSampleBlock;
    st.gatherSamples(lanes);
    st.forwardPass();
    st.lossGradient(loss);
    st.backpropagate();
    st.sumGradient();
    st.adamStep();
}

}  // namespace NRAD_LOCKSTEP_KERNELS
}  // namespace nrad
