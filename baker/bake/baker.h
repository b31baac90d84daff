// Baker: the whole bake of one scene: voxel grid, training samples, one network per occupied voxel
// (trained in parallel), and the asset they make. Deterministic for a scene, settings and seed.
#pragma once

#include <functional>
#include <string>
#include <vector>

#include <nrad/format.h>

#include "baker/bake/bake_group.h"
#include "baker/bake/bake_shard.h"
#include "baker/bake/partition.h"
#include "baker/bake/trainer.h"
#include "baker/bake/training_samples.h"
#include "baker/bake/volume_samples.h"
#include "baker/scene/scene.h"

namespace nrad {

// How the networks' targets are made (paper Sec. 3 and 5).
enum class TrainingMethod {
    MonteCarlo,  // each sample's target from `paths` full paths (SampleSettings)
    Integral,  // within the integral equation: a bounce or two, the networks themselves standing in for the rest
};
const char* trainingMethodName(TrainingMethod method);
bool parseTrainingMethod(const std::string& name, TrainingMethod& method);

// Training within the integral equation: a Monte Carlo start (the usual bake, SampleSettings' points and
// paths, few of them, while the networks know nothing), then `generations` rounds, each of fresh points
// continuing the quasi-Monte Carlo sequence, whose targets are `bounces` bounce(s) of next event estimation and BSDF
// sampling with the networks as they stood after the previous round for the rest of the path
// (NetworkField), each sample used for `epochs` passes and then dropped; the learning rate falls
// geometrically from `learningRate` to `finalLearningRate` over the rounds.
struct IntegralSettings {
    uint32_t generations = 8;
    uint32_t points = 0;  // per round; 0: 2,000 per network, at least 50,000
    uint32_t paths = 2;  // target estimates per point in a round
    // The start's training, short: it only has to give the first round's targets something to stand on (at
    // most these epochs and patience, the first of TrainSettings::weightDecays only). (300 epochs, with the
    // command's 750 start points per cell, left the rounds a start they needed many of to undo: results.md.)
    int startEpochs = 1000, startPatience = 50;
    // Initialisations per start network, the lowest held-out error kept (TrainSettings::restarts); 0: automatic,
    // 4 for bakes of 32 rounds or more (where the start costs little and one network's poor start, which the
    // rounds do not undo, is what remains), else 1 (restarts()).
    int startRestarts = 0;
    int restarts() const { return startRestarts > 0 ? startRestarts : (generations >= 32 ? 4 : 1); }
    int bounces = 2;
    int epochs = 4;
    float learningRate = 0.01f, finalLearningRate = 0.0005f;
    float averageDecay = 0.99f;  // per step, of the parameters' moving average (0: none)
};

struct BakeSettings {
    glm::uvec3 grid{3, 3, 3};
    // Half-width, in voxels, of the band around interior voxel faces where neighbouring networks are blended
    // (nrad/eval.h supports()); each network trains on its voxel plus this margin. 0: no blending, seams.
    float blendBand = 0.0625f;
    // With a byte budget, an adaptive kd-tree partition replaces the grid (partition.h); `grid` then only sets
    // the per-voxel floor of training samples.
    PartitionSettings partition;
    // Without a budget: the grid's cells split at walls (partition.h), so that no network holds both sides.
    WallSplitSettings walls;
    SampleSettings samples;
    TrainSettings train;
    TrainingMethod training = TrainingMethod::MonteCarlo;
    IntegralSettings integral;
    format::WeightEncoding encoding = format::WeightEncoding::Float16;
    NeeSettings nee;  // light selection of the training paths (learned: trained on warm-up paths first)
    // The light in the volume (VVOX, VWGT; issue 42): networks of the same cells for receivers that were not in
    // the bake. Off by default (it costs about what the surfaces' sampling does).
    VolumeSettings volume;
    bool metadata = true;
    // The command-line lighting this bake used (sun, engine-drawn lights) as a JSON object, recorded in the
    // metadata so that validate and render --asset can light the scene the same way. Empty: none.
    std::string lightingJson;
};

struct BakeTimings {
    double setup = 0.0, sampling = 0.0, partition = 0.0, training = 0.0;  // partition: refining the kd-tree (--budget)
    double volume = 0.0;  // the volume's samples and networks
};

// One round of training within the integral equation (round 0: the Monte Carlo start).
struct GenerationStats {
    uint32_t generation = 0;
    size_t samples = 0;
    uint64_t rays = 0;
    double samplingSeconds = 0.0, trainingSeconds = 0.0;
    double heldOutRelMse = 0.0;  // mean over networks, against this round's targets
    float learningRate = 0.0f;
};

struct BakeResult {
    format::Asset asset;
    std::vector<VoxelTrainResult> voxels;  // occupied voxels (tree: leaves with surface), in index order
    AdaptivePartition partition;  // with a budget: the tree, its leaves and what refining it gained
    SampleStats sampleStats;
    size_t sampleCount = 0;
    double surfaceArea = 0.0;
    BakeTimings timings;
    std::vector<GenerationStats> generations;  // integral training: every round, the start included
    std::vector<VoxelTrainResult> volume;  // the volume's networks (BakeSettings::volume), in cell order
    VolumeStats volumeStats;
    std::vector<VoxelTrainResult> glossy;  // its glossy response (VolumeSettings::glossy), in cell order
    VolumeStats glossyStats;
};

struct BakeProgress {
    std::function<void(double)> sampling;
    std::function<void(double)> training;
    // Integral training: called after every round (0: the Monte Carlo start) with the asset as it stands.
    std::function<void(uint32_t generation, const BakeResult& soFar)> generation;
    // A budget's partition (refinePartition): the fraction of the networks it pays for made so far.
    std::function<void(double)> partition;
};

// The settings' automatic values, where SampleSettings' points or paths are 0 (what `nrad bake` and every
// library caller get alike):
// - paths: kMonteCarloPaths, or kIntegralStartPaths for the Monte Carlo start of integral training;
// - points: a Monte Carlo grid, kBasePoints per 27 cells (at least kBasePoints: fewer per cell make each network a
//   block of its own noise, docs/results.md); with a budget, as many for every network it pays for
//   (kPointsPerNetwork: a tree's leaves as densely sampled as a grid's cells, so that a finer asset is not a
//   noisier one: at 1,500 a network, the doorway scene's 64 KB tree had 3.6x fewer samples than grid 6 and more
//   error); integral training on a grid, kIntegralPointsPerCell per cell (at least kIntegralMinPoints);
//   at most kMaxAutomaticPoints, so that a large bake stays in minutes.
constexpr uint32_t kMonteCarloPaths = 32, kIntegralStartPaths = 4;
constexpr uint32_t kBasePoints = 160000, kPointsPerNetwork = kBasePoints / 27, kIntegralPointsPerCell = 1500,
                   kIntegralMinPoints = 40000;
constexpr uint32_t kMaxAutomaticPoints = 4000000;
BakeSettings resolvedBakeSettings(BakeSettings settings);
// The samples of a bake at the defaults, resolved (what validate's baseline falls back on).
const SampleSettings& defaultBakeSamples();

// Bakes with resolvedBakeSettings(settings). group: the processes baking it together (MPI ranks), each tracing its
// share of the points and training its share of the networks (assigned by samples, largest first), every
// process ending with the whole result, the same bytes as one process's; nullptr: this process alone.
BakeResult bakeScene(const Scene& scene, const BakeSettings& settings, const BakeProgress& progress = {},
                     const BakeGroup* group = nullptr);

// Shards (bake_shard.h): the bake split among processes that never meet, through part files. Monte Carlo bakes
// only (integral training exchanges its networks between rounds: std::invalid_argument, kShardsNotIntegral).
constexpr const char* kShardsNotIntegral =
    "shards bake with Monte Carlo training only: training within the integral equation exchanges the networks between "
    "its rounds (bake it on MPI processes with mpirun, or shard it with --training monte-carlo)";
// Stage 1: this shard's share of the traced points, as the messages of a part (tracedSamplesPayload); `stats`, if
// given, gets the sampling's counts and times.
std::vector<std::vector<uint8_t>> traceShard(const Scene& scene, const BakeSettings& settings, ShardId shard,
                                             const BakeProgress& progress = {}, BakeResult* stats = nullptr);
// Stage 2: the bake with this shard's networks trained and the others' left zero in their places; `trained`: the
// indices (into result.voxels and the asset's voxels) of its own. group: the shard, with the stage-1 parts to
// replay (or none: it traces every point itself).
BakeResult bakeShard(const Scene& scene, const BakeSettings& settings, const ShardGroup& group, const BakeProgress& progress,
                     std::vector<uint32_t>& trained);

// The networks' shape as the asset records it: hidden widths, weight encoding, output transform (the loss's).
format::Topology bakeTopology(const BakeSettings& settings);

// Compact JSON written into the asset's META section: only content that is the same for every identical
// bake (tool, settings, scene hash, per-voxel held-out error), never timings.
std::string assetMetadata(const Scene& scene, const BakeSettings& settings, const BakeResult& result);

// FNV-1a 64-bit hash of the scene as imported and lit (geometry, materials, lights, the active environment):
// what the bake depends on. Recorded in the asset; validate and render --asset compare it.
uint64_t sceneHash(const Scene& scene);

}  // namespace nrad
