// Forward pass and backpropagation of the per-voxel networks.
#include "baker/nn/mlp.h"

#include <algorithm>
#include <cmath>

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

void Mlp::forward(const float* x, float* y, MlpWorkspace& ws) const {
    size_t layers = shape_.hidden.size() + 1;
    ws.activations.resize(layers + 1);
    ws.activations[0].assign(x, x + shape_.inputs);
    const float* p = params_.data();
    int in = shape_.inputs;
    for (size_t l = 0; l < layers; ++l) {
        bool last = l + 1 == layers;
        int out = last ? shape_.outputs : shape_.hidden[l];
        const float* W = p;
        const float* b = p + size_t(out) * size_t(in);
        std::vector<float>& a = ws.activations[l + 1];
        a.resize(size_t(out));
        const std::vector<float>& prev = ws.activations[l];
        for (int o = 0; o < out; ++o) {
            float s = b[o];
            for (int i = 0; i < in; ++i) s += W[size_t(o) * size_t(in) + size_t(i)] * prev[size_t(i)];
            a[size_t(o)] = last ? s : std::max(0.0f, s);
        }
        p = b + out;
        in = out;
    }
    std::copy(ws.activations[layers].begin(), ws.activations[layers].end(), y);
}

void Mlp::backward(const float* dy, MlpWorkspace& ws, float* grad) const {
    size_t layers = shape_.hidden.size() + 1;
    ws.deltas.resize(layers + 1);
    const std::vector<size_t>& offset = offset_;
    ws.deltas[layers].assign(dy, dy + shape_.outputs);
    for (size_t l = layers; l-- > 0;) {
        int out = l + 1 == layers ? shape_.outputs : shape_.hidden[l];
        int in = l == 0 ? shape_.inputs : shape_.hidden[l - 1];
        const float* W = params_.data() + offset[l];
        float* gW = grad + offset[l];
        float* gb = gW + size_t(out) * size_t(in);
        const std::vector<float>& prev = ws.activations[l];
        const std::vector<float>& delta = ws.deltas[l + 1];
        for (int o = 0; o < out; ++o) {
            float d = delta[size_t(o)];
            if (d == 0.0f) continue;
            gb[o] += d;
            for (int i = 0; i < in; ++i) gW[size_t(o) * size_t(in) + size_t(i)] += d * prev[size_t(i)];
        }
        if (l == 0) break;
        std::vector<float>& back = ws.deltas[l];
        back.assign(size_t(in), 0.0f);
        for (int i = 0; i < in; ++i) {
            if (prev[size_t(i)] <= 0.0f) continue;  // ReLU'(z) = 0 for inactive units
            float s = 0.0f;
            for (int o = 0; o < out; ++o) s += W[size_t(o) * size_t(in) + size_t(i)] * delta[size_t(o)];
            back[size_t(i)] = s;
        }
    }
}

bool Mlp::allFinite() const {
    return std::all_of(params_.begin(), params_.end(), [](float p) { return std::isfinite(p); });
}

}  // namespace nrad
