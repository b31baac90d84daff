// The pieces that training a voxel's network is made of, shared by the lockstep training of many networks
// (trainer_lockstep.cpp) and the rounds of training within the integral equation (trainer.cpp): a network's
// samples as the optimizer sees them, its error as shaded, and the checks made after training. Private to
// baker/bake.
#pragma once

#include <string>
#include <vector>

#include <glm/glm.hpp>

#include "baker/bake/trainer.h"

namespace nrad {
namespace trainer_detail {

// A network's samples as the optimizer sees them: encoded inputs, targets (demodulated if asked), the
// reflectance they are multiplied back by, per-channel loss weights (demodulation's and the blend weight),
// and the held-out split, a hash of (seed, voxel, sample, salt), at least one on each side.
struct PreparedSamples {
    const std::vector<VoxelSample>* entries = nullptr;
    std::vector<float> inputs;
    std::vector<glm::vec3> targets, modulation, weights;
    std::vector<size_t> train, heldOut;
    const std::vector<size_t>& evalSet() const { return heldOut.empty() ? train : heldOut; }  // one sample: judged on itself
    const TrainingSample& sample(size_t i) const { return *(*entries)[i].sample; }
    float blend(size_t i) const { return (*entries)[i].weight; }
};

PreparedSamples prepareSamples(uint32_t voxel, const std::vector<VoxelSample>& entries, const TrainSettings& settings, uint32_t salt);

// Weighted relMSE over `set` as shaded: the prediction multiplied back by the reflectance, against the
// scattered radiance, weighted as the runtime weighs this network there.
double shadedError(const Mlp& mlp, MlpBatchWorkspace& ws, const PreparedSamples& d, const std::vector<size_t>& set,
                   const TrainSettings& settings, format::OutputTransform transform, float scale);

// Whether every target of the network is grey (its three channels within 1e-4 of their mean): no colour to learn.
bool greyTargets(const PreparedSamples& d);

// The output layer's three rows (weights and bias) replaced by their mean: the network then outputs the mean of
// its channels in each, grey, with a luminance error no larger than the channels' mean error (convexity).
void averageOutputs(std::vector<float>& params, const NetworkShape& shape);

// Whether an attempt at training failed, and how: non-finite weights (`nonFinite`), every first-layer ReLU dead
// on every training input, or an output that does not depend on the input although the targets vary.
std::string attemptFailure(const Mlp& mlp, const PreparedSamples& d, const std::vector<size_t>& train, const TrainSettings& settings,
                           float invScale, bool nonFinite);

}  // namespace trainer_detail
}  // namespace nrad
