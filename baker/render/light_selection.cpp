// Uniform and learned light selection; the selection network's forward and backward passes and training.
#include "baker/render/light_selection.h"

#include <algorithm>
#include <cmath>
#include <limits>

namespace nrad {

namespace {

// Softmax of the logits over the groups in `mask` (others get 0).
void maskedSoftmax(const float* logits, size_t count, uint64_t mask, float* out) {
    float m = -std::numeric_limits<float>::infinity();
    for (size_t g = 0; g < count; ++g)
        if (mask >> g & 1u) m = std::max(m, logits[g]);
    float sum = 0.0f;
    for (size_t g = 0; g < count; ++g) {
        out[g] = (mask >> g & 1u) ? std::exp(logits[g] - m) : 0.0f;
        sum += out[g];
    }
    for (size_t g = 0; g < count; ++g) out[g] = sum > 0.0f ? out[g] / sum : 0.0f;
}

// The layers, compiled for AVX-512 and AVX2+FMA as well as the baseline and picked when the program loads
// (GCC's function multi-versioning; the loops over 64 outputs vectorise). Same machine, same code path:
// results stay deterministic.
#if defined(__x86_64__) && defined(__GNUC__) && !defined(__clang__)
#define NRAD_NEE_CLONES __attribute__((target_clones("arch=x86-64-v4", "arch=x86-64-v3", "default")))
#else
#define NRAD_NEE_CLONES
#endif
// Helpers are inlined into each clone so they are compiled for its target too.
#if defined(__GNUC__)
#define NRAD_NEE_INLINE inline __attribute__((always_inline))
#else
#define NRAD_NEE_INLINE inline
#endif

// out = relu(bias + sum_i in[i] W[i]); accumulators are locals so they stay in registers (no aliasing with the
// weights). No test for zero inputs: with ReLU inputs it mispredicts half the time and costs more than it saves.
// Generic vectors of 16 floats (GCC vector extensions): each clone maps them onto its own registers. Two
// partial sums (even and odd rows) halve the chain of dependent FMAs that bounds a matrix-vector product.
typedef float Vec16 __attribute__((vector_size(64)));

template <int N, bool Relu>
NRAD_NEE_INLINE void dense(const float* __restrict W, const float* __restrict bias, const float* __restrict in, int inCount,
                           float* __restrict out) {
    constexpr int V = N / 16;
    Vec16 acc0[V], acc1[V];
#pragma GCC unroll 8
    for (int v = 0; v < V; ++v) {
        __builtin_memcpy(&acc0[v], bias + 16 * v, sizeof(Vec16));
        acc1[v] = Vec16{};
    }
    int i = 0;
    for (; i + 1 < inCount; i += 2) {
        const float* __restrict r0 = W + i * N;
        const float* __restrict r1 = r0 + N;
        Vec16 s0 = Vec16{} + in[i], s1 = Vec16{} + in[i + 1];
#pragma GCC unroll 8
        for (int v = 0; v < V; ++v) {
            Vec16 w0, w1;
            __builtin_memcpy(&w0, r0 + 16 * v, sizeof(Vec16));
            __builtin_memcpy(&w1, r1 + 16 * v, sizeof(Vec16));
            acc0[v] += s0 * w0;
            acc1[v] += s1 * w1;
        }
    }
    if (i < inCount) {
        const float* __restrict r0 = W + i * N;
        Vec16 s0 = Vec16{} + in[i];
#pragma GCC unroll 8
        for (int v = 0; v < V; ++v) {
            Vec16 w0;
            __builtin_memcpy(&w0, r0 + 16 * v, sizeof(Vec16));
            acc0[v] += s0 * w0;
        }
    }
#pragma GCC unroll 8
    for (int v = 0; v < V; ++v) {
        Vec16 r = acc0[v] + acc1[v];
        if (Relu) r = r > Vec16{} ? r : Vec16{};
        __builtin_memcpy(out + 16 * v, &r, sizeof(Vec16));
    }
}

NRAD_NEE_CLONES void forwardLayers(const float* P, int Kp, const float* x, NeeNetwork::Activations& a) {
    const float* W1 = P;
    const float* B1 = W1 + kNeeInputs * kNeeHidden;
    const float* W2 = B1 + kNeeHidden;
    const float* B2 = W2 + kNeeHidden * kNeeHidden;
    const float* W3 = B2 + kNeeHidden;
    const float* B3 = W3 + kNeeHidden * Kp;
    dense<kNeeHidden, true>(W1, B1, x, kNeeInputs, a.h1);
    dense<kNeeHidden, true>(W2, B2, a.h1, kNeeHidden, a.h2);
    switch (Kp) {  // the output rows are padded to one of these widths
        case 16: dense<16, false>(W3, B3, a.h2, kNeeHidden, a.logits); break;
        case 32: dense<32, false>(W3, B3, a.h2, kNeeHidden, a.logits); break;
        default: dense<64, false>(W3, B3, a.h2, kNeeHidden, a.logits); break;
    }
}

NRAD_NEE_CLONES void backwardLayers(const float* P, int K, const float* x, const NeeNetwork::Activations& a,
                                    const float* dLogits, float* grad) {
    const size_t w1 = 0, b1 = kNeeInputs * kNeeHidden, w2 = b1 + kNeeHidden, b2 = w2 + kNeeHidden * kNeeHidden,
                 w3 = b2 + kNeeHidden, b3 = w3 + size_t(kNeeHidden) * size_t(K);
    float d2[kNeeHidden], d1[kNeeHidden];
    for (int o = 0; o < K; ++o) grad[b3 + size_t(o)] += dLogits[o];
    for (int i = 0; i < kNeeHidden; ++i) {
        const float* row = P + w3 + size_t(i) * size_t(K);
        float* g = grad + w3 + size_t(i) * size_t(K);
        float s = 0.0f;
        for (int o = 0; o < K; ++o) {
            g[o] += a.h2[i] * dLogits[o];
            s += row[o] * dLogits[o];
        }
        d2[i] = a.h2[i] > 0.0f ? s : 0.0f;
    }
    for (int o = 0; o < kNeeHidden; ++o) {
        grad[b2 + size_t(o)] += d2[o];
        d1[o] = 0.0f;
    }
    for (int i = 0; i < kNeeHidden; ++i) {
        if (a.h1[i] <= 0.0f) continue;
        const float* row = P + w2 + size_t(i) * kNeeHidden;
        float* g = grad + w2 + size_t(i) * kNeeHidden;
        float s = 0.0f;
        for (int o = 0; o < kNeeHidden; ++o) {
            g[o] += a.h1[i] * d2[o];
            s += row[o] * d2[o];
        }
        d1[i] = s;
    }
    for (int o = 0; o < kNeeHidden; ++o) grad[b1 + size_t(o)] += d1[o];
    for (int i = 0; i < kNeeInputs; ++i) {
        float* g = grad + w1 + size_t(i) * kNeeHidden;
        for (int o = 0; o < kNeeHidden; ++o) g[o] += x[i] * d1[o];
    }
}

}  // namespace

const char* neeModeName(NeeMode mode) {
    switch (mode) {
        case NeeMode::Power: return "power";
        case NeeMode::Uniform: return "uniform";
        case NeeMode::Learned: return "learned";
    }
    return "?";
}

NeeNetwork::NeeNetwork(int outputs, uint64_t seed)
    : outputs_(std::clamp(outputs, 1, int(LightSampler::kMaxLightGroups))),
      padded_(outputs_ <= 16 ? 16 : outputs_ <= 32 ? 32 : 64) {
    params_.assign(b3() + size_t(padded_), 0.0f);
    SplitMix64 rng(seed ^ 0x6e65656e6574ull);
    auto fill = [&](size_t at, int fanIn, size_t count) {
        float bound = std::sqrt(6.0f / float(fanIn));  // He uniform
        for (size_t i = 0; i < count; ++i) params_[at + i] = (2.0f * rng.uniform() - 1.0f) * bound;
    };
    const size_t b1 = size_t(kNeeInputs) * kNeeHidden, w2 = b1 + kNeeHidden, b2 = w2 + size_t(kNeeHidden) * kNeeHidden;
    fill(0, kNeeInputs, size_t(kNeeInputs) * kNeeHidden);
    fill(w2, kNeeHidden, size_t(kNeeHidden) * kNeeHidden);
    for (int i = 0; i < kNeeHidden; ++i) fill(w3() + size_t(i) * size_t(padded_), kNeeHidden, size_t(outputs_));
    for (int i = 0; i < kNeeHidden; ++i) params_[b1 + size_t(i)] = params_[b2 + size_t(i)] = 0.01f;
    // Output layer starts small: an almost uniform distribution until the first contributions arrive.
    // Padding columns stay zero: their gradient is zero.
    for (size_t i = 0; i < size_t(kNeeHidden) * size_t(padded_); ++i) params_[w3() + i] *= 0.1f;
}

void NeeNetwork::forward(const float* x, Activations& a) const { forwardLayers(params_.data(), padded_, x, a); }

void NeeNetwork::backward(const float* x, const Activations& a, const float* dLogits, float* grad) const {
    backwardLayers(params_.data(), padded_, x, a, dLogits, grad);
}

LightSelector::LightSelector(const LightSampler& lights, const Bounds3& sceneBounds, const NeeSettings& settings)
    : lights_(lights),
      settings_(settings),
      network_(int(std::max<size_t>(lights.groupCount(), 1)), settings.seed),
      adam_(network_.parameters().size(), settings.learningRate) {
    settings_.mix = std::clamp(settings_.mix, 1e-3f, 1.0f);
    settings_.batchesPerRound = std::max(1, settings_.batchesPerRound);
    settings_.trainBatches = std::max(1, settings_.trainBatches);
    if (!sceneBounds.empty()) {
        boundsCenter_ = sceneBounds.center();
        glm::vec3 half = 0.5f * sceneBounds.extent();
        for (int a = 0; a < 3; ++a) boundsScale_[a] = half[a] > 0.0f ? 1.0f / half[a] : 0.0f;
    }
}

void LightSelector::input(const glm::vec3& p, const glm::vec3& ns, const glm::vec3& wo, float* x) const {
    glm::vec3 q = glm::clamp((p - boundsCenter_) * boundsScale_, glm::vec3(-1.0f), glm::vec3(1.0f));
    x[0] = q.x, x[1] = q.y, x[2] = q.z;
    x[3] = ns.x, x[4] = ns.y, x[5] = ns.z;
    x[6] = -wo.x, x[7] = -wo.y, x[8] = -wo.z;  // the direction the path arrived along
}

uint64_t LightSelector::candidates(const glm::vec3& p, const glm::vec3& ng) const {
    uint64_t mask = 0;
    for (size_t g = 0; g < lights_.groupCount(); ++g)
        if (lights_.groupCanContribute(g, p, ng)) mask |= uint64_t(1) << g;
    return mask;
}

void LightSelector::networkDistribution(const glm::vec3& p, const glm::vec3& ns, const glm::vec3& wo,
                                        uint64_t mask, float* probs) const {
    float x[kNeeInputs];
    input(p, ns, wo, x);
    NeeNetwork::Activations a;
    network_.forward(x, a);
    maskedSoftmax(a.logits, lights_.groupCount(), mask, probs);
}

bool LightSelector::distribution(const glm::vec3& p, const glm::vec3& ng, const glm::vec3& ns, const glm::vec3& wo,
                                 int depth, float* probs, NeeRecord* record) const {
    const size_t G = lights_.groupCount();
    if (settings_.mode != NeeMode::Learned) {
        for (size_t g = 0; g < G; ++g) probs[g] = 1.0f / float(G);
        return false;
    }
    uint64_t mask = candidates(p, ng);
    int count = __builtin_popcountll(mask);
    if (count <= 1 || settings_.mix >= 1.0f || (settings_.networkVertices > 0 && depth >= settings_.networkVertices)) {
        for (size_t g = 0; g < G; ++g) probs[g] = (mask >> g & 1u) ? 1.0f / float(count) : 0.0f;
        return false;
    }
    float x[kNeeInputs];
    input(p, ns, wo, x);
    NeeNetwork::Activations a;
    network_.forward(x, a);
    maskedSoftmax(a.logits, G, mask, probs);
    const float mix = settings_.mix, share = mix / float(count);
    for (size_t g = 0; g < G; ++g)
        if (mask >> g & 1u) probs[g] = (1.0f - mix) * probs[g] + share;
    if (record) {
        std::copy(x, x + kNeeInputs, record->input);
        record->candidates = mask;
        record->light = 0;
        record->weight = 0.0f;
    }
    return true;
}

void LightSelector::train(const std::vector<NeeRecord>& records, float lrScale) {
    if (settings_.mode != NeeMode::Learned || !settings_.train) return;
    std::vector<const NeeRecord*> useful;
    for (const NeeRecord& r : records)
        if (r.weight > 0.0f && std::isfinite(r.weight) && r.light < lights_.groupCount()) useful.push_back(&r);
    if (useful.empty()) return;
    const size_t cap = size_t(settings_.trainBatches) * 64;
    if (useful.size() > cap) {
        std::vector<const NeeRecord*> spread(cap);
        for (size_t k = 0; k < cap; ++k) spread[k] = useful[k * useful.size() / cap];
        useful.swap(spread);
    }
    const size_t G = lights_.groupCount();
    std::vector<float>& params = network_.parameters();
    std::vector<float> grad(params.size()), saved;
    for (size_t begin = 0; begin < useful.size(); begin += 64) {
        size_t end = std::min(useful.size(), begin + 64);
        // Contribution-weighted cross-entropy, sum_k w_k (-log q(light_k | x_k)) / sum_k w_k: its gradient
        // estimates that of the KL divergence from the normalised contributions to the network's distribution.
        double wsum = 0.0;
        for (size_t k = begin; k < end; ++k) wsum += double(useful[k]->weight);
        std::fill(grad.begin(), grad.end(), 0.0f);
        float dLogits[LightSampler::kMaxLightGroups] = {}, q[LightSampler::kMaxLightGroups];
        for (size_t k = begin; k < end; ++k) {
            const NeeRecord& r = *useful[k];
            NeeNetwork::Activations a;
            network_.forward(r.input, a);
            maskedSoftmax(a.logits, G, r.candidates, q);
            float w = float(double(r.weight) / wsum);
            for (size_t g = 0; g < G; ++g) dLogits[g] = w * (q[g] - (g == r.light ? 1.0f : 0.0f));
            network_.backward(r.input, a, dLogits, grad.data());
        }
        saved = params;
        adam_.step(params, grad, settings_.learningRate * lrScale);
        if (!std::all_of(params.begin(), params.end(), [](float v) { return std::isfinite(v); })) {
            params.swap(saved);
            ++rejectedSteps_;
        } else {
            ++steps_;
        }
    }
}

}  // namespace nrad
