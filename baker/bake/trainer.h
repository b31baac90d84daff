// Trainer: fits one voxel's network to its training samples, a short loop over baker/nn's pieces (network,
// loss, optimizer, schedule): held-out split for early stopping and the reported error, deterministic
// initialisation and sample order from the seed, HDR-aware losses, detection of failed trainings (non-finite
// weights, dead ReLUs, constant output) with re-initialisation, and a constant fallback so nothing invalid is
// ever kept. continueVoxel: the same pieces for the rounds of training within the integral equation.
#pragma once

#include <algorithm>
#include <cstdint>
#include <functional>
#include <memory>
#include <string>
#include <vector>

#include <glm/glm.hpp>
#include <nrad/eval.h>
#include <nrad/format.h>

#include "baker/nn/adam.h"
#include "baker/nn/loss.h"
#include "baker/nn/mlp.h"
#include "baker/bake/training_samples.h"
#include "baker/bake/voxel_grid.h"

namespace nrad {

struct TrainSettings {
    NetworkShape shape;
    int epochs = 500;
    int batchSize = 32;
    float learningRate = 0.01f;  // decays exponentially to a tenth over the epochs
    float holdoutFraction = 0.1f;
    int patience = 100;  // epochs without a better held-out error before stopping
    LossKind loss = LossKind::RelativeL2;
    uint32_t seed = 0;
    int maxAttempts = 3;
    int curveEvery = 5;  // record the held-out error every N epochs
    // Learn the scattered radiance divided by the surface's reflectance (nrad/eval.h, kFlagDemodulated), so
    // the networks learn lighting and the material (textures included) is multiplied back when shading.
    bool demodulate = true;
    // L2 penalties on the weights (not the output biases) to choose from, each lambda / (the number of the
    // network's training samples, its blending margin's included), so that it fades as data grows: every voxel trains once per candidate and keeps the one with
    // the lowest held-out error. 0 alone trains once, unregularised (docs/training.md).
    std::vector<float> weightDecays = {0.0f, 2.5f};
    // Initialisations per weight decay: each trains from its own random start and the lowest held-out error
    // wins (1: one, the first). Three by default: which sharp feature a network of nine hidden units catches
    // depends on its start, and one start per decay left a dark room's floor a block 22% too bright beside
    // a doorway's light for one seed in three, at two grids (docs/results.md, docs/training.md). The glossy box, whose
    // targets are the noisiest, came out 8% worse (0.00360 against 0.00332 with one start): the choice among six
    // candidates fits the noise of their held-out samples there.
    int restarts = 3;
    // The race: after this many epochs the starts of each weight decay are compared by their lowest held-out error so
    // far; the one ahead trains on to its end and the others stop there; the decays' survivors are compared at their
    // ends (0: every candidate trains to its end). 0 by default: at 100 the training takes about half as long, but the
    // furnace's worst error at albedo 0.99 went from 1.2% to 5.1% and the doorway's worst block at grid 4 from 7.4-10.3%
    // to 10.7-11.8% (docs/training.md). With raceAll every candidate races every other, the decays included: at 200
    // epochs that took the furnace to 10.4% (the decay ahead at epoch 200 is not the one that ends best).
    int raceEpochs = 0;
    bool raceAll = false;
    // Each epoch's held-out check judges, and the training keeps, a moving average of the parameters over the epochs
    // instead of the parameters themselves: with noisy targets the optimiser's parameters wander about the fit by its
    // step, and the average removes most of that (docs/training.md). The decay per epoch is min(this,
    // (1 + e) / (10 + e)) at epoch e, so that an early best is not weighed down by the first epochs; 0: none.
    float epochAverage = 0.9f;
    // A network whose targets are all grey outputs the mean of its three channels (its output rows averaged after
    // training): no colour where its data has none. Each channel's own noise otherwise tints it (a grey room
    // came out pink, green and purple: docs/results.md).
    bool greyWhereGrey = true;
};

// The candidates one race compares (TrainSettings::raceEpochs): a weight decay's starts, or every candidate (raceAll).
inline size_t raceGroup(const TrainSettings& s) {
    const size_t restarts = size_t(std::max(1, s.restarts));
    return s.raceAll ? std::max<size_t>(1, s.weightDecays.size()) * restarts : restarts;
}
// Whether the training races at all: a race epoch and something to compare.
inline bool raced(const TrainSettings& s) { return s.raceEpochs > 0 && raceGroup(s) > 1; }

struct TrainCurvePoint {
    int epoch;
    double seconds;  // since this voxel's training started
    double heldOutRelMse;
};

struct VoxelTrainResult {
    uint32_t voxel = 0;
    std::vector<float> params;
    float scale = 1.0f;  // radiance = scale x transform(y)
    format::OutputTransform transform = format::OutputTransform::ClampedLinear;
    size_t trainCount = 0, heldOutCount = 0;
    double heldOutRelMse = 0.0;  // mean over held-out samples and channels of (L - ref)^2 / (ref^2 + 0.01)
    double trainRelMse = 0.0;
    int epochs = 0;  // of the kept attempt
    int attempts = 0;
    bool fallback = false;  // every attempt failed: a constant network was stored
    float weightDecay = 0.0f;  // the kept candidate of TrainSettings::weightDecays
    std::vector<std::string> events;  // what went wrong in failed attempts
    std::vector<TrainCurvePoint> curve;
    double seconds = 0.0;
};


// A training sample as one network sees it: its weight there (the blend weight the runtime gives that
// network at the sample's position, 1 without blending) and its position input relative to the voxel.
struct VoxelSample {
    const TrainingSample* sample = nullptr;
    float weight = 1.0f;
    glm::vec3 local{0.0f};
};

// The samples of every voxel's network: with band 0, each voxel's own samples; with a band, every sample
// within reach of a voxel (its voxel plus the band's margin) with the weight and position input of
// eval::supports() and keepOccupied(), where a voxel is occupied when it holds samples of its own. Indexed
// by voxel; the order is the samples' order.
std::vector<std::vector<VoxelSample>> samplesByNetwork(const VoxelGrid& grid, float band, const std::vector<TrainingSample>& samples);
// The same for any partition (the grid or a kd-tree): cellOfSample[i] is sample i's own cell (a cell is
// occupied when it holds one), ownPosition(i) its position input there when it lies just outside the box.
std::vector<std::vector<VoxelSample>> samplesByNetwork(const eval::Partition& partition, const std::vector<uint32_t>& cellOfSample,
                                                       const std::vector<TrainingSample>& samples,
                                                       const std::function<glm::vec3(size_t)>& ownPosition);
// Radiance from the network's outputs.
glm::vec3 decodeOutput(format::OutputTransform transform, float scale, const float y[3]);
// relMSE of one prediction against its reference (mean over the three channels).
double relativeSquaredError(const glm::vec3& prediction, const glm::vec3& reference);

// Fits the network of `voxel` to its samples, each weighing VoxelSample::weight in the loss, the scale
// and the reported (weighted) errors.
VoxelTrainResult trainVoxel(uint32_t voxel, const std::vector<VoxelSample>& samples, const TrainSettings& settings);
// The same for many voxels at once (trainer_lockstep.cpp): every training (a voxel under one weight decay and
// initialisation) runs in a lane of networks trained in lockstep (baker/nn/mlp_lockstep.h), the lanes on the
// threads of the current task arena; result k is trainVoxel(voxels[k], *samples[k], settings), bit for bit, whatever
// the threads or the other voxels. onDone (if given) is called once per voxel as it finishes, from any thread.
std::vector<VoxelTrainResult> trainVoxels(const std::vector<uint32_t>& voxels, const std::vector<const std::vector<VoxelSample>*>& samples,
                                          const TrainSettings& settings, const std::function<void()>& onDone = {});
// A network between the generations of training within the integral equation (baker.h): what it has become
// (parameters, fixed output scale, the errors of its latest generation) and its optimizer's state.
struct NetworkState {
    VoxelTrainResult result;  // its params: what the asset and the targets use (the average, if averaged)
    std::vector<float> params;  // what the optimizer steps
    std::unique_ptr<Adam> adam;  // created at the first generation
};

// Trains state's network further, `epochs` passes over `samples` (a new generation's, whose targets came from
// the networks as they were) from where it stood, at a constant learning rate (scaled down in proportion when
// the round has more than 512 steps, so that what a round moves does not grow with the samples). With
// averageDecay > 0 the network kept is an exponential moving average of the optimizer's parameters over its
// steps (decay per step, continuing across generations): the noise of one-bounce targets averages out. The
// held-out split is salted with the generation. The gradient stops at the targets (semi-gradient). Returns
// state.result, updated: its errors are this generation's, against its (noisy) targets.
VoxelTrainResult continueVoxel(const std::vector<VoxelSample>& samples, const TrainSettings& settings, uint32_t generation, int epochs,
                               float learningRate, float averageDecay, NetworkState& state);
// The same for samples inside the voxel, weight 1 each.
VoxelTrainResult trainVoxel(const VoxelGrid& grid, uint32_t voxel, const std::vector<const TrainingSample*>& samples,
                            const TrainSettings& settings);

}  // namespace nrad
