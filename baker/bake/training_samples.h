// Training samples (paper Sec. 5): surface points uniform by area (scrambled Sobol), one outgoing direction
// each, uniform on the hemisphere around the shading normal, and the radiance L(x, wo) - Le(x, wo) it
// scatters (full transport, without its own emission, which is exact and added back when shading) estimated
// by the path tracer with `paths` paths. Voxels with surface but too few samples get extra points from
// their own surface (the per-voxel floor).
#pragma once

#include <cstdint>
#include <functional>
#include <vector>

#include <glm/glm.hpp>
#include <nrad/eval.h>

#include "baker/bake/bake_group.h"
#include "baker/bake/voxel_grid.h"
#include "baker/render/path_tracer.h"

namespace nrad {

// Russian roulette for training targets (PathTracer::setRouletteThreshold): paths are followed until their
// throughput falls below 0.1 before roulette may end them. At high albedo a path's many bounces are then
// summed instead of sampled by a geometric length, a lower worst asset error for more sampling time
// (docs/design.md). Renders keep 1.
constexpr float kTrainingRouletteThreshold = 0.1f;

struct TrainingSample {
    glm::vec3 position;  // world space
    glm::vec3 normal;  // unit shading normal, on the side of wo
    glm::vec3 wo;  // unit, away from the surface
    glm::vec3 radiance;  // scattered radiance: mean of the finite path estimates minus the point's emission
    uint32_t voxel;
    glm::vec3 reflectance{1.0f};  // eval::reflectance of the point's material towards wo (for demodulation)
};

// What a demodulated network learns for sample t is t.radiance / this (the reflectance, floored).
inline glm::vec3 demodulationDivisor(const TrainingSample& t) { return glm::max(t.reflectance, glm::vec3(eval::kMinReflectance)); }

struct SampleSettings {
    // 0: chosen by the bake from its other settings (resolvedBakeSettings, baker.h); must be set otherwise.
    uint32_t points = 0;
    uint32_t paths = 0;
    int maxDepth = 0;  // segments, counting the (virtual) one that reached the point; 0 = unbounded (issue 38)
    uint32_t seed = 0;
    uint32_t minSamplesPerVoxel = 64;  // the floor for voxels with surface area
    // Drop points no viewer can see from their direction wo (PathTracer::viewable: the view ray meets the
    // back of a single-sided surface first): their targets, dark, would otherwise be drawn by the same
    // network as the lit surface next to them.
    bool dropHidden = true;
    // Learned light selection (the tracer's selector in learned mode): paths traced from the training points,
    // before the samples, to train the selection network, which then stays fixed (so samples can be traced
    // in any order). Their estimates are not used.
    uint64_t neeWarmupPaths = 262144;
    // Generations of training within the integral equation (baker.h): this set's points continue the point
    // sequence at index `firstPoint`, and its floor points and paths are salted with `generation` (0: none).
    uint32_t firstPoint = 0;
    uint32_t generation = 0;
    // Noisy targets get more paths (Monte Carlo targets only): a point whose mean's relative standard error r
    // (luminance, over its `paths` estimates) exceeds b = noisyRelativeError gets the paths that bring it to b,
    // paths x ((r / b)^2 - 1) more, at most (extraPathsFactor - 1) x paths, decided per point from its own
    // estimates (any threads, the same samples). 1: off. The default, 4, lowers the glossy box's and the
    // interiors' errors (docs/usage.md, "--noisy-paths").
    uint32_t extraPathsFactor = 4;
    float noisyRelativeError = 0.15f;
};

// The extra paths of a point whose n finite path estimates (luminance) have the mean `mean` and the sample variance
// `variance`: those that bring the relative standard error of its mean to settings.noisyRelativeError, paths x
// ((r / b)^2 - 1) rounded up, at most (extraPathsFactor - 1) x paths; 0 within the bound, with a factor of 1 or a
// mean of 0.
uint32_t noisyExtraPaths(double mean, double variance, uint32_t n, const SampleSettings& settings);
// The same from a point's `count` path estimates (the luminance of the finite ones); 0 with fewer than two.
uint32_t noisyExtraPaths(const glm::vec3* estimates, uint32_t count, const SampleSettings& settings);

// How a sample's target is estimated: `paths` full paths (Monte Carlo), or, with a tail, `paths` estimates of
// `bounces` bounces each with the tail standing in for the rest (PathTracer::scatteredRadiance).
struct TargetEstimator {
    const ScatteredRadiance* tail = nullptr;
    int bounces = 1;
};

struct SampleStats {
    uint64_t points = 0;  // from the global, area-uniform pass
    uint64_t floorPoints = 0;  // added to voxels below the floor
    uint64_t nonFinitePaths = 0;  // path estimates that were NaN or Inf: dropped
    uint64_t droppedSamples = 0;  // points whose every path estimate was non-finite
    uint64_t hiddenSamples = 0;  // points no viewer sees from their direction (dropped, SampleSettings::dropHidden)
    uint64_t noisyPoints = 0;  // points that got extra paths (SampleSettings::extraPathsFactor)
    uint64_t extraPaths = 0;  // the paths they got beyond SampleSettings::paths
    RayCounters rays;
    std::vector<uint32_t> perVoxel;  // samples per voxel after the floor
    uint64_t neeWarmupPaths = 0, neeTrainingSteps = 0;
    double neeWarmupSeconds = 0.0;
    double planSeconds = 0.0;  // deciding the points (area pass, who sees them, the floor): every process of a group alike
};

// trainee: the tracer's light selector if it is to be trained (learned mode), else nullptr. group: the processes
// of the bake, each tracing its share of the points (every process gets every sample: the same as one process).
std::vector<TrainingSample> generateTrainingSamples(const Scene& scene, const PathTracer& tracer, const VoxelGrid& grid,
                                                    const SurfacePieces& pieces, const SampleSettings& settings,
                                                    SampleStats& stats,
                                                    const std::function<void(double)>& progress = {},
                                                    LightSelector* trainee = nullptr, const TargetEstimator& estimator = {},
                                                    const BakeGroup* group = nullptr);

}  // namespace nrad
