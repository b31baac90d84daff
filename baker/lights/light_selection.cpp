// Light selection by power, uniform and learned; the selection network's forward and backward passes and training.
#include "baker/lights/light_selection.h"

#include <algorithm>
#include <cmath>

#include <tbb/parallel_for.h>

#include "baker/nn/loss.h"

namespace nrad {

const char* neeModeName(NeeMode mode) {
    switch (mode) {
        case NeeMode::Power: return "power";
        case NeeMode::Uniform: return "uniform";
        case NeeMode::Learned: return "learned";
    }
    return "?";
}

LightSelector::LightSelector(const LightSampler& lights, const Bounds3& sceneBounds, const NeeSettings& settings)
    : lights_(lights),
      settings_(settings),
      network_(int(std::max<size_t>(lights.groupCount(), 1)), settings.seed),
      adam_(network_.parameters().size()) {
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

LightChoice LightSelector::sample(const LightSampleContext& ctx, glm::vec2 u, float* probs, NeeRecord* record) const {
    LightChoice c;
    if (choosesGroups()) {
        c.networkEvaluated = distribution(ctx, probs, record);
        c.ls = sampleGroups(probs, u, ctx.p, c.group);
    } else if (!lights_.empty()) {
        c.ls = lights_.sample(ctx.p, u);
    }
    return c;
}

float LightSelector::pdfTriangle(const float* probs, uint32_t triangle, const glm::vec3& from, const glm::vec3& pLight,
                                 const glm::vec3& nLight) const {
    if (!choosesGroups()) return lights_.pdfTriangle(triangle, from, pLight, nLight);
    const int32_t g = lights_.groupOfTriangle(triangle);
    return g < 0 ? 0.0f : probs[g] * lights_.pdfTriangleInGroup(triangle, from, pLight, nLight);
}

LightSample LightSelector::sampleGroups(const float* probs, glm::vec2 u, const glm::vec3& p, int& chosen) const {
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

bool LightSelector::distribution(const LightSampleContext& ctx, float* probs, NeeRecord* record) const {
    const glm::vec3 &p = ctx.p, &ng = ctx.ng, &ns = ctx.ns, &wo = ctx.wo;
    const int depth = ctx.depth;
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
        // by brightness only (measured against these: docs/design.md).
        double wsum = 0.0;
        for (size_t k = begin; k < end; ++k) wsum += double(useful[k]->weight) * double(useful[k]->weight);
        // The gradient in fixed chunks of the mini-batch, in parallel, summed in chunk order: the same bits
        // for any number of threads.
        const size_t chunks = (end - begin + kTrainChunk - 1) / kTrainChunk;
        chunkGrad_.resize(std::max(chunkGrad_.size(), chunks));
        tbb::parallel_for(size_t(0), chunks, [&](size_t c) {
            std::vector<float>& g = chunkGrad_[c];
            g.assign(params.size(), 0.0f);
            float dLogits[LightSampler::kMaxLightGroups] = {};
            for (size_t k = begin + c * kTrainChunk; k < std::min(end, begin + (c + 1) * kTrainChunk); ++k) {
                const NeeRecord& r = *useful[k];
                NeeNetwork::Activations a;
                network_.forward(r.input, a);
                const float w = float(double(r.weight) * double(r.weight) / wsum);
                crossEntropyGradient(a.logits, G, r.candidates, r.light, w, dLogits);
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
