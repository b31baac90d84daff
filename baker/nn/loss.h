// The losses of the baker's networks, as the gradient with respect to the network's outputs:
// regression for the voxel networks (radiance, per channel, with per-channel weights) and the weighted
// softmax cross-entropy of the light selector (a distribution over candidate groups).
#pragma once

#include <cstddef>
#include <cstdint>
#include <string>

namespace nrad {

enum class LossKind {
    L2,  // squared error on radiance / voxel scale
    RelativeL2,  // squared error / (luminance of the prediction^2 + 0.01), prediction held constant
    // squared error / (the mean of the prediction's and the target's luminance^2 + 0.01), prediction held constant:
    // a prediction far above a dark target is not excused by its own brightness (the volume's networks)
    SymmetricRelativeL2,
    Log,  // squared error on log(1 + radiance / scale); the asset's output transform is then exponential
    // the symmetric relative loss of the exponential output p = exp(y) - 1 (radiance / scale) against the linear
    // target, with the floor 1 / kExpScaleFraction^2 times SymmetricRelativeL2's (the same share of the mean):
    // the volume's networks, whose light spans an emitter's radiance to a corner's indirect light in one cell.
    // The scale is kExpScaleFraction of the mean, so that exp covers the dark end as a ratio, not a line.
    SymmetricRelativeExp,
};
constexpr float kExpScaleFraction = 0.1f;  // SymmetricRelativeExp: the network's scale over its cell's mean luminance

const char* lossName(LossKind loss);
bool parseLoss(const std::string& name, LossKind& loss);

// The output transform the asset decodes a network trained with `loss` by (format::OutputTransform): 1 exponential
// (Log, SymmetricRelativeExp), 0 clamped linear.
bool exponentialOutput(LossKind loss);
// The network's output scale over its training targets' mean luminance (1, or kExpScaleFraction).
float scaleFraction(LossKind loss);
// The output biases a network starts from: the mean target (1 / scaleFraction) through the output transform.
float initialOutputBias(LossKind loss);
// The regression target in the network's output space: t / scale, through log(1 + .) for the Log loss.
float lossTarget(LossKind loss, float invScale, float target);

// dLoss/dy for one sample of three outputs y against targets t (in the output space, lossTarget), each channel
// weighing weight[c].
void regressionGradient(LossKind loss, const float y[3], const float t[3], const float weight[3], float dy[3]);

// Softmax of the logits over the entries in `mask` (bit g; others get 0).
void maskedSoftmax(const float* logits, size_t count, uint64_t mask, float* out);

// dLoss/dLogits of weight x (-log softmax(logits)[chosen]) over the entries in `mask`: weight (q - onehot).
void crossEntropyGradient(const float* logits, size_t count, uint64_t mask, size_t chosen, float weight, float* dLogits);

}  // namespace nrad
