// Regression and cross-entropy gradients.
#include "baker/nn/loss.h"

#include <algorithm>
#include <cmath>
#include <limits>

#include "nrad/eval.h"

namespace nrad {

const char* lossName(LossKind loss) {
    switch (loss) {
        case LossKind::L2: return "l2";
        case LossKind::RelativeL2: return "relative-l2";
        case LossKind::SymmetricRelativeL2: return "symmetric-relative-l2";
        case LossKind::Log: return "log-l2";
        case LossKind::SymmetricRelativeExp: return "symmetric-relative-exp";
    }
    return "?";
}

bool parseLoss(const std::string& name, LossKind& loss) {
    for (LossKind k : {LossKind::L2, LossKind::RelativeL2, LossKind::SymmetricRelativeL2, LossKind::Log, LossKind::SymmetricRelativeExp})
        if (name == lossName(k)) {
            loss = k;
            return true;
        }
    return false;
}

bool exponentialOutput(LossKind loss) { return loss == LossKind::Log || loss == LossKind::SymmetricRelativeExp; }

float scaleFraction(LossKind loss) { return loss == LossKind::SymmetricRelativeExp ? kExpScaleFraction : 1.0f; }

float initialOutputBias(LossKind loss) {
    if (loss == LossKind::Log) return std::log(2.0f);  // log(1 + 1)
    if (loss == LossKind::SymmetricRelativeExp) return std::log(1.0f + 1.0f / kExpScaleFraction);
    return 1.0f;
}

float lossTarget(LossKind loss, float invScale, float target) {
    float t = target * invScale;
    return loss == LossKind::Log ? std::log1p(std::max(0.0f, t)) : t;
}

namespace {

// The luminance of the positive parts (what the relative losses scale by).
inline float positiveLuminance(const float v[3]) {
    return 0.2126f * std::max(0.0f, v[0]) + 0.7152f * std::max(0.0f, v[1]) + 0.0722f * std::max(0.0f, v[2]);
}

}  // namespace

void regressionGradient(LossKind loss, const float y[3], const float t[3], const float weight[3], float dy[3]) {
    float w = 1.0f;
    if (loss == LossKind::RelativeL2) {
        const float l = positiveLuminance(y);
        w = 1.0f / (l * l + 0.01f);
    } else if (loss == LossKind::SymmetricRelativeL2) {
        const float l = positiveLuminance(y), m = positiveLuminance(t);
        w = 1.0f / (0.5f * (l * l + m * m) + 0.01f);
    } else if (loss == LossKind::SymmetricRelativeExp) {
        // dL/dy = dL/dp (p + 1), p = exp(y) - 1 as the asset decodes it (eval::expMinusOne: the same bits everywhere),
        // y taken at most 30 (p = 1e13 of the scale: p^2 stays finite, and so the gradient, of a diverging network)
        const float p[3] = {eval::expMinusOne(std::min(y[0], 30.0f)), eval::expMinusOne(std::min(y[1], 30.0f)),
                            eval::expMinusOne(std::min(y[2], 30.0f))};
        const float l = positiveLuminance(p), m = positiveLuminance(t);
        constexpr float kFloor = 0.01f / (kExpScaleFraction * kExpScaleFraction);
        w = 1.0f / (0.5f * (l * l + m * m) + kFloor);
        for (int c = 0; c < 3; ++c) dy[c] = 2.0f * w * weight[c] * (p[c] - t[c]) * (p[c] + 1.0f);
        return;
    }
    for (int c = 0; c < 3; ++c) dy[c] = 2.0f * w * weight[c] * (y[c] - t[c]);
}

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

void crossEntropyGradient(const float* logits, size_t count, uint64_t mask, size_t chosen, float weight, float* dLogits) {
    float q[64];
    maskedSoftmax(logits, std::min<size_t>(count, 64), mask, q);
    for (size_t o = 0; o < std::min<size_t>(count, 64); ++o) dLogits[o] = weight * (q[o] - (o == chosen ? 1.0f : 0.0f));
}

}  // namespace nrad
