// Forward pass and backpropagation of the per-voxel networks.
#include "baker/nn/mlp.h"

#include <algorithm>
#include <cmath>

#include "baker/nn/mlp_batch.h"

namespace nrad {

size_t NetworkShape::parameterCount() const {
    size_t n = 0, in = size_t(inputs);
    for (int w : hidden) {
        n += size_t(w) * in + size_t(w);
        in = size_t(w);
    }
    return n + size_t(outputs) * in + size_t(outputs);
}

int NetworkShape::maxWidth() const {
    int m = std::max(inputs, outputs);
    for (int w : hidden) m = std::max(m, w);
    return m;
}

Mlp::Mlp(NetworkShape shape) : shape_(std::move(shape)), params_(shape_.parameterCount(), 0.0f) {
    size_t at = 0;
    int in = shape_.inputs;
    const size_t layers = shape_.hidden.size() + 1;
    for (size_t l = 0; l < layers; ++l) {
        int out = l + 1 == layers ? shape_.outputs : shape_.hidden[l];
        offset_.push_back(at);
        at += size_t(out) * size_t(in) + size_t(out);
        in = out;
    }
}

void Mlp::initialize(uint64_t seed, float outputBias) {
    SplitMix64 rng(seed);
    size_t at = 0;
    int in = shape_.inputs;
    size_t layers = shape_.hidden.size() + 1;
    for (size_t l = 0; l < layers; ++l) {
        bool last = l + 1 == layers;
        int out = last ? shape_.outputs : shape_.hidden[l];
        float limit = std::sqrt(6.0f / float(in));
        for (int i = 0; i < out * in; ++i) params_[at++] = (2.0f * rng.uniform() - 1.0f) * limit;
        for (int i = 0; i < out; ++i) params_[at++] = last ? outputBias : 0.01f;
        in = out;
    }
}

namespace {
void prepare(const NetworkShape& shape, MlpWorkspace& ws) {
    const size_t layers = shape.hidden.size() + 1;
    if (ws.at.size() == layers + 2) return;
    ws.at.assign(1, 0);
    ws.at.push_back(size_t(shape.inputs));
    for (size_t l = 0; l < layers; ++l) ws.at.push_back(ws.at.back() + size_t(l + 1 == layers ? shape.outputs : shape.hidden[l]));
    ws.values.assign(ws.at.back(), 0.0f);
    ws.deltas.assign(ws.at.back(), 0.0f);
}
}  // namespace

// Each output's sum runs from its bias up in input order (as nrad/eval.h's forward), all outputs of a layer at
// once so that their chains overlap.
void Mlp::forward(const float* x, float* y, MlpWorkspace& ws) const {
    prepare(shape_, ws);
    const size_t layers = shape_.hidden.size() + 1;
    std::copy(x, x + shape_.inputs, ws.values.begin());
    int in = shape_.inputs;
    for (size_t l = 0; l < layers; ++l) {
        const bool last = l + 1 == layers;
        const int out = last ? shape_.outputs : shape_.hidden[l];
        const float* W = params_.data() + offset_[l];
        const float* b = W + size_t(out) * size_t(in);
        const float* prev = ws.values.data() + ws.at[l];
        float* a = ws.values.data() + ws.at[l + 1];
        for (int o = 0; o < out; ++o) a[o] = b[o];
        for (int i = 0; i < in; ++i) {
            const float xi = prev[i];
            for (int o = 0; o < out; ++o) a[o] += W[size_t(o) * size_t(in) + size_t(i)] * xi;
        }
        if (!last)
            for (int o = 0; o < out; ++o) a[o] = std::max(0.0f, a[o]);
        in = out;
    }
    std::copy(ws.values.begin() + std::ptrdiff_t(ws.at[layers]), ws.values.begin() + std::ptrdiff_t(ws.at[layers + 1]), y);
}

void Mlp::backward(const float* dy, MlpWorkspace& ws, float* grad) const {
    const size_t layers = shape_.hidden.size() + 1;
    std::copy(dy, dy + shape_.outputs, ws.deltas.begin() + std::ptrdiff_t(ws.at[layers]));
    for (size_t l = layers; l-- > 0;) {
        const int out = l + 1 == layers ? shape_.outputs : shape_.hidden[l];
        const int in = l == 0 ? shape_.inputs : shape_.hidden[l - 1];
        const float* W = params_.data() + offset_[l];
        float* gW = grad + offset_[l];
        float* gb = gW + size_t(out) * size_t(in);
        const float* prev = ws.values.data() + ws.at[l];
        const float* delta = ws.deltas.data() + ws.at[l + 1];
        for (int o = 0; o < out; ++o) {
            const float d = delta[o];
            if (d == 0.0f) continue;
            gb[o] += d;
            for (int i = 0; i < in; ++i) gW[size_t(o) * size_t(in) + size_t(i)] += d * prev[i];
        }
        if (l == 0) break;
        // The previous layer's deltas: each a sum over outputs in output order, zero for inactive units.
        float* back = ws.deltas.data() + ws.at[l];
        for (int i = 0; i < in; ++i) back[i] = 0.0f;
        for (int o = 0; o < out; ++o) {
            const float d = delta[o];
            for (int i = 0; i < in; ++i) back[i] += W[size_t(o) * size_t(in) + size_t(i)] * d;
        }
        for (int i = 0; i < in; ++i)
            if (prev[i] <= 0.0f) back[i] = 0.0f;  // ReLU'(z) = 0 for inactive units
    }
}

namespace {

constexpr int B = MlpBatchWorkspace::kMaxBatch;

void prepareBatch(const NetworkShape& shape, MlpBatchWorkspace& ws) {
    const size_t layers = shape.hidden.size() + 1;
    if (ws.at.size() == layers + 2) return;
    ws.at.assign(1, 0);
    ws.at.push_back(size_t(shape.inputs) * B);
    for (size_t l = 0; l < layers; ++l) ws.at.push_back(ws.at.back() + size_t(l + 1 == layers ? shape.outputs : shape.hidden[l]) * B);
    ws.values.assign(ws.at.back(), 0.0f);
    ws.deltas.assign(ws.at.back(), 0.0f);
}

}  // namespace

void Mlp::forwardBatch(const float* x, int count, MlpBatchWorkspace& ws) const {
    prepareBatch(shape_, ws);
    ws.count = count;
    // AVX2 where the CPU has it (the same bits either way). NRAD_MLP_BASELINE_ONLY: the baseline's kernels only
    // (tests of what machines without AVX2 run).
#if defined(__x86_64__) && !defined(NRAD_MLP_BASELINE_ONLY)
    if (cpuHasAvx2()) return mlp_avx2::forwardBatch(shape_, params_, offset_, x, count, ws);
#endif
    mlp_sse2::forwardBatch(shape_, params_, offset_, x, count, ws);
}

void Mlp::backwardBatch(MlpBatchWorkspace& ws, float* grad) const {
#if defined(__x86_64__) && !defined(NRAD_MLP_BASELINE_ONLY)
    if (cpuHasAvx2()) return mlp_avx2::backwardBatch(shape_, params_, offset_, ws, grad);
#endif
    mlp_sse2::backwardBatch(shape_, params_, offset_, ws, grad);
}

bool Mlp::allFinite() const {
    return std::all_of(params_.begin(), params_.end(), [](float p) { return std::isfinite(p); });
}

}  // namespace nrad
