// Baker: the whole bake of one scene: voxel grid, training samples, one network per occupied voxel
// (trained in parallel), and the asset they make. Deterministic for a scene, settings and seed.
#pragma once

#include <functional>
#include <string>
#include <vector>

#include <nrad/format.h>

#include "baker/bake/partition.h"
#include "baker/bake/trainer.h"
#include "baker/bake/training_samples.h"
#include "baker/scene/scene.h"

namespace nrad {

struct BakeSettings {
    glm::uvec3 grid{3, 3, 3};
    // Half-width, in voxels, of the band around interior voxel faces where neighbouring networks are blended
    // (nrad/eval.h supports()); each network trains on its voxel plus this margin. 0: no blending, seams.
    float blendBand = 0.0625f;
    // With a byte budget, an adaptive kd-tree partition replaces the grid (partition.h); `grid` then only sets
    // the per-voxel floor of training samples.
    PartitionSettings partition;
    SampleSettings samples;
    TrainSettings train;
    format::WeightEncoding encoding = format::WeightEncoding::Float16;
    NeeSettings nee;  // light selection of the training paths (learned: trained on warm-up paths first)
    bool metadata = true;
    // The command-line lighting this bake used (sun, engine-drawn lights) as a JSON object, recorded in the
    // metadata so that validate and render --asset can light the scene the same way. Empty: none.
    std::string lightingJson;
};

struct BakeTimings {
    double setup = 0.0, sampling = 0.0, partition = 0.0, training = 0.0;  // partition: refining the kd-tree (--budget)
};

struct BakeResult {
    format::Asset asset;
    std::vector<VoxelTrainResult> voxels;  // occupied voxels (tree: leaves with surface), in index order
    AdaptivePartition partition;  // with a budget: the tree, its leaves and what refining it gained
    SampleStats sampleStats;
    size_t sampleCount = 0;
    double surfaceArea = 0.0;
    BakeTimings timings;
};

struct BakeProgress {
    std::function<void(double)> sampling;
    std::function<void(double)> training;
};

BakeResult bakeScene(const Scene& scene, const BakeSettings& settings, const BakeProgress& progress = {});

// Compact JSON written into the asset's META section: only content that is the same for every identical
// bake (tool, settings, scene hash, per-voxel held-out error), never timings.
std::string assetMetadata(const Scene& scene, const BakeSettings& settings, const BakeResult& result);

// FNV-1a 64-bit hash of the scene as imported and lit (geometry, materials, lights, the active environment):
// what the bake depends on. Recorded in the asset; validate and render --asset compare it.
uint64_t sceneHash(const Scene& scene);

}  // namespace nrad
