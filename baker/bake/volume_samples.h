// Training samples of the light in the scene's volume (issue 42): what a receiver that was not in the bake (a
// moving object) gets at a point of free space. The quantity: the radiance a white Lambertian receiver at x
// facing n scatters, E(x, n) / pi (E: the irradiance on a plane through x with normal n), for any unit n. The
// networks of the volume learn it with the surfaces' inputs (position in the cell, n, and n again as the
// direction) and the surfaces' training; nrad/eval.h's volume query reads it back.
#pragma once

#include <cstdint>
#include <vector>

#include <nrad/eval.h>

#include "baker/bake/training_samples.h"
#include "baker/render/path_tracer.h"
#include "baker/scene/scene.h"

namespace nrad {

struct VolumeSettings {
    bool enabled = false;  // nrad bake --volume-points N (N > 0)
    uint32_t pointsPerCell = 1000;  // tried in each cell's box (those inside a closed solid are dropped)
    uint32_t paths = 32;  // per point
    // Noisy targets get more paths, as the surfaces' do (SampleSettings::extraPathsFactor and noisyRelativeError,
    // which the bake copies here): up to extraPathsFactor x paths in all; 1: none.
    uint32_t extraPathsFactor = 1;
    float noisyRelativeError = 0.15f;
    // Also the glossy response (nrad bake --volume-glossy): networks of the same cells for the radiance a GGX
    // receiver of roughness eval::kGlossyRoughness and Fresnel 1 reflects towards a viewer, over eval::glossyAlbedo.
    bool glossy = false;
};

struct VolumeStats {
    uint64_t tried = 0, inside = 0;  // points tried; of them inside a closed solid (dropped)
    uint64_t rays = 0;
    uint64_t noisyPoints = 0, extraPaths = 0;  // points that got more paths (VolumeSettings::extraPathsFactor), and those paths
    double seconds = 0.0;
};

// Points uniform in every cell of `partition` (a voxel or a kd-tree leaf), in cell order, dropped where a ray in
// either of two random directions first meets the back of an opaque single-sided surface (inside a closed
// solid, or behind a surface lying on another); each with a uniform random unit normal, its target E(x, n) / pi
// from `paths` paths of the tracer (next event estimation and BSDF sampling of a white Lambertian receiver, cut at
// maxDepth segments: 0 unbounded), and more for a noisy one (VolumeSettings::extraPathsFactor), `voxel` its cell,
// reflectance 1. Deterministic for a seed, whatever the threads.
// glossy: the glossy response's samples instead (eval.h's glossy query): the same points tried (another normal), each
// with a direction v towards a viewer uniform over the hemisphere of its normal (TrainingSample::wo), its target
// the radiance the GGX receiver (glossyReceiverAt) reflects towards v over eval::glossyAlbedo(n.v).
std::vector<TrainingSample> generateVolumeSamples(const PathTracer& tracer, const eval::Partition& partition,
                                                  const VolumeSettings& settings, uint32_t seed, int maxDepth, VolumeStats& stats,
                                                  bool glossy = false);

// The interaction of a white Lambertian receiver at p facing n (a plane through p that is in no scene): the start
// of its paths.
SurfaceInteraction receiverAt(const glm::vec3& p, const glm::vec3& n);

// A white metallic GGX receiver of roughness eval::kGlossyRoughness (Fresnel 1) at p facing n, seen from v.
SurfaceInteraction glossyReceiverAt(const glm::vec3& p, const glm::vec3& n, const glm::vec3& v);

}  // namespace nrad
