// Uniform and learned light selection; the selection network's forward and backward passes and training.
#include "baker/lights/light_selection.h"

#include <algorithm>
#include <cmath>
#include <limits>

#include <tbb/parallel_for.h>

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
// Generic vectors of 16 floats (GCC vector extensions): each clone maps them onto its own registers. S partial
// sums (rows i, i + S, ... go to sum i mod S) split the chain of dependent FMAs that bounds a matrix-vector
// product: at least 8 independent chains in all, so narrow layers (the output) get more partial sums.
typedef float Vec16 __attribute__((vector_size(64)));

template <int N, int InCount, bool Relu>
NRAD_NEE_INLINE void dense(const float* __restrict W, const float* __restrict bias, const float* __restrict in,
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

NRAD_NEE_CLONES void forwardLayers(const float* P, int Kp, const float* x, NeeNetwork::Activations& a) {
    const float* W1 = P;
    const float* B1 = W1 + kNeeInputs * kNeeHidden;
    const float* W2 = B1 + kNeeHidden;
    const float* B2 = W2 + kNeeHidden * kNeeHidden;
    const float* W3 = B2 + kNeeHidden;
    const float* B3 = W3 + kNeeHidden * Kp;
    dense<kNeeHidden, kNeeInputs, true>(W1, B1, x, a.h1);
    dense<kNeeHidden, kNeeHidden, true>(W2, B2, a.h1, a.h2);
    switch (Kp) {  // the output rows are padded to one of these widths
        case 16: dense<16, kNeeHidden, false>(W3, B3, a.h2, a.logits); break;
        case 32: dense<32, kNeeHidden, false>(W3, B3, a.h2, a.logits); break;
        default: dense<64, kNeeHidden, false>(W3, B3, a.h2, a.logits); break;
    }
}

// Sum of a vector's lanes in lane order (a fixed order: the same bits on every run of one code path).
NRAD_NEE_INLINE float laneSum(const Vec16& v) {
    float s = 0.0f;
#pragma GCC unroll 16
    for (int l = 0; l < 16; ++l) s += v[l];
    return s;
}

// Vectors pass by reference: a 64-byte vector by value would change the ABI between the clones.
NRAD_NEE_INLINE void load16(Vec16& v, const float* p) { __builtin_memcpy(&v, p, sizeof(Vec16)); }

NRAD_NEE_INLINE void addTo16(float* p, const Vec16& v) {
    Vec16 x;
    load16(x, p);
    x += v;
    __builtin_memcpy(p, &x, sizeof(Vec16));
}

NRAD_NEE_INLINE void fmaRow(const float* p, const Vec16& a, Vec16& s) {
    Vec16 w;
    load16(w, p);
    s += w * a;
}

// One row of a layer's backward pass: g += h delta (the weight gradient of input h) and the row's dot product
// with delta (the input's delta before its ReLU), for V vectors of 16 outputs.
template <int V>
NRAD_NEE_INLINE float backRow(const float* row, float* g, float h, const Vec16* delta) {
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
NRAD_NEE_INLINE void backwardPadded(const float* P, const float* x, const NeeNetwork::Activations& a, const float* dLogits,
                                    float* grad) {
    constexpr int VK = K / 16, VH = kNeeHidden / 16;
    const size_t w1 = 0, b1 = kNeeInputs * kNeeHidden, w2 = b1 + kNeeHidden, b2 = w2 + kNeeHidden * kNeeHidden,
                 w3 = b2 + kNeeHidden, b3 = w3 + size_t(kNeeHidden) * size_t(K);
    alignas(64) float d2[kNeeHidden], d1[kNeeHidden];
    Vec16 dl[VK];
#pragma GCC unroll 4
    for (int v = 0; v < VK; ++v) {
        load16(dl[v], dLogits + 16 * v);
        addTo16(grad + b3 + 16 * v, dl[v]);
    }
    for (int i = 0; i < kNeeHidden; ++i) {
        float s = backRow<VK>(P + w3 + size_t(i) * K, grad + w3 + size_t(i) * K, a.h2[i], dl);
        d2[i] = a.h2[i] > 0.0f ? s : 0.0f;
    }
    Vec16 d2v[VH];
#pragma GCC unroll 4
    for (int v = 0; v < VH; ++v) {
        load16(d2v[v], d2 + 16 * v);
        addTo16(grad + b2 + 16 * v, d2v[v]);
    }
    for (int i = 0; i < kNeeHidden; ++i)  // rows of inactive units add nothing to the gradient: skipped
        d1[i] = a.h1[i] > 0.0f ? backRow<VH>(P + w2 + size_t(i) * kNeeHidden, grad + w2 + size_t(i) * kNeeHidden, a.h1[i], d2v)
                               : 0.0f;
    Vec16 d1v[VH];
#pragma GCC unroll 4
    for (int v = 0; v < VH; ++v) {
        load16(d1v[v], d1 + 16 * v);
        addTo16(grad + b1 + 16 * v, d1v[v]);
    }
    for (int i = 0; i < kNeeInputs; ++i) {
        Vec16 xi = Vec16{} + x[i];
#pragma GCC unroll 4
        for (int v = 0; v < VH; ++v) addTo16(grad + w1 + size_t(i) * kNeeHidden + 16 * v, xi * d1v[v]);
    }
}

NRAD_NEE_CLONES void backwardLayers(const float* P, int Kp, const float* x, const NeeNetwork::Activations& a,
                                    const float* dLogits, float* grad) {
    switch (Kp) {  // the output rows are padded to one of these widths
        case 16: backwardPadded<16>(P, x, a, dLogits, grad); break;
        case 32: backwardPadded<32>(P, x, a, dLogits, grad); break;
        default: backwardPadded<64>(P, x, a, dLogits, grad); break;
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
    return lights_.candidateGroups(p, ng);
}

void LightSelector::networkDistribution(const glm::vec3& p, const glm::vec3& ns, const glm::vec3& wo,
                                        uint64_t mask, float* probs) const {
    float x[kNeeInputs];
    input(p, ns, wo, x);
    NeeNetwork::Activations a;
    network_.forward(x, a);
    maskedSoftmax(a.logits, lights_.groupCount(), mask, probs);
}

LightSample LightSelector::sample(const float* probs, glm::vec2 u, const glm::vec3& p, int& chosen) const {
    const size_t groups = lights_.groupCount();
    chosen = -1;
    float acc = 0.0f, before = 0.0f;
    for (size_t g = 0; g < groups; ++g) {
        if (!(probs[g] > 0.0f)) continue;
        chosen = int(g);
        before = acc;
        acc += probs[g];
        if (u.x < acc) break;
    }
    if (chosen < 0) return LightSample{};
    const float pick = probs[chosen];
    const float uIn = std::clamp((u.x - before) / pick, 0.0f, 0x1.fffffep-1f);
    LightSample ls = lights_.sampleGroup(size_t(chosen), p, glm::vec2(uIn, u.y));
    ls.pdf *= pick;
    return ls;
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
    quantize(probs, G, mask, count);
    if (record) {
        std::copy(x, x + kNeeInputs, record->input);
        record->candidates = mask;
        record->light = 0;
        record->weight = 0.0f;
    }
    return true;
}

void LightSelector::quantize(float* probs, size_t G, uint64_t mask, int count) const {
    // Whole units of 1 / quantum, at least one per candidate, the rest by largest remainder (ties: lower
    // group first); the units add up to the quantum exactly.
    const int U = settings_.quantum;
    if (U <= 0 || count > U) return;
    int units[LightSampler::kMaxLightGroups] = {}, total = 0;
    float rem[LightSampler::kMaxLightGroups] = {};
    for (size_t g = 0; g < G; ++g)
        if (mask >> g & 1u) {
            float scaled = probs[g] * float(U);
            units[g] = std::max(1, int(scaled));
            rem[g] = scaled - float(units[g]);
            total += units[g];
        }
    while (total != U) {
        int best = -1;
        for (size_t g = 0; g < G; ++g) {
            if (!(mask >> g & 1u)) continue;
            bool better = total < U ? (best < 0 || rem[g] > rem[best]) : (units[g] > 1 && (best < 0 || rem[g] < rem[best]));
            if (better) best = int(g);
        }
        if (best < 0) return;  // cannot happen: count <= U
        if (total < U) {
            ++units[best], rem[best] -= 1.0f, ++total;
        } else {
            --units[best], rem[best] += 1.0f, --total;
        }
    }
    for (size_t g = 0; g < G; ++g) probs[g] = (mask >> g & 1u) ? float(units[g]) / float(U) : 0.0f;
}

void LightSelector::train(const std::vector<NeeRecord>& records, float lrScale, int maxSteps) {
    if (settings_.mode != NeeMode::Learned || !settings_.train) return;
    std::vector<const NeeRecord*> useful;
    for (const NeeRecord& r : records)
        if (r.weight > 0.0f && std::isfinite(r.weight) && r.light < lights_.groupCount()) useful.push_back(&r);
    if (useful.empty()) return;
    const size_t cap = size_t(std::max(0, std::min(settings_.trainBatches, maxSteps))) * 64;
    if (cap == 0) return;
    if (useful.size() > cap) {
        std::vector<const NeeRecord*> spread(cap);
        for (size_t k = 0; k < cap; ++k) spread[k] = useful[k * useful.size() / cap];
        useful.swap(spread);
    }
    const size_t G = lights_.groupCount();
    std::vector<float>& params = network_.parameters();
    std::vector<float> grad, saved;
    for (size_t begin = 0; begin < useful.size(); begin += 64) {
        size_t end = std::min(useful.size(), begin + 64);
        // Weighted cross-entropy sum_k w_k^2 (-log q(light_k | x_k)) / sum_k w_k^2, w_k = contribution / pdf
        // of the sample. With samples drawn from p, its minimiser is q_j ~ E_j[w^2] p_j, so at the fixed point
        // q = p: q_j ~ sqrt(second moment of light j's estimate), the selection of least variance when the
        // pick is stratified (each light then gets its share of a pixel's samples exactly and only the
        // estimates within a light vary). Weights w (the KL divergence, q_j ~ mean contribution) favour lights
        // by brightness only: measured on split-rooms, 2.57-2.75x against 2.56-2.79x at 128 x 128 and
        // 2.43-2.47x against 2.47-2.55x at 256 x 256 (docs/results.md).
        double wsum = 0.0;
        for (size_t k = begin; k < end; ++k) wsum += double(useful[k]->weight) * double(useful[k]->weight);
        // The gradient in fixed chunks of the mini-batch, in parallel, summed in chunk order: the same bits
        // for any number of threads.
        const size_t chunks = (end - begin + kTrainChunk - 1) / kTrainChunk;
        chunkGrad_.resize(std::max(chunkGrad_.size(), chunks));
        tbb::parallel_for(size_t(0), chunks, [&](size_t c) {
            std::vector<float>& g = chunkGrad_[c];
            g.assign(params.size(), 0.0f);
            float dLogits[LightSampler::kMaxLightGroups] = {}, q[LightSampler::kMaxLightGroups];
            for (size_t k = begin + c * kTrainChunk; k < std::min(end, begin + (c + 1) * kTrainChunk); ++k) {
                const NeeRecord& r = *useful[k];
                NeeNetwork::Activations a;
                network_.forward(r.input, a);
                maskedSoftmax(a.logits, G, r.candidates, q);
                float w = float(double(r.weight) * double(r.weight) / wsum);
                for (size_t o = 0; o < G; ++o) dLogits[o] = w * (q[o] - (o == r.light ? 1.0f : 0.0f));
                network_.backward(r.input, a, dLogits, g.data());
            }
        });
        grad = chunkGrad_[0];
        for (size_t c = 1; c < chunks; ++c)
            for (size_t i = 0; i < grad.size(); ++i) grad[i] += chunkGrad_[c][i];
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
