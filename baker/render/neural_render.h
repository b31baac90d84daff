// Rendering through a neural radiance asset, as an engine would: the primary ray finds the first surface,
// and the runtime's public C API evaluates the radiance leaving it towards the camera (wo = -ray
// direction, the shading normal on the viewer's side). Box-filtered over `spp` jittered samples per pixel.
#pragma once

#include <nrad/nrad.h>

#include "baker/render/accel.h"
#include "baker/render/image_io.h"
#include "baker/render/path_tracer.h"
#include "baker/scene/scene.h"

namespace nrad {

struct NeuralRenderStats {
    double seconds = 0.0;  // wall time of the whole render
    double visibilitySeconds = 0.0;  // summed over threads: primary rays and surface interactions
    double evaluationSeconds = 0.0;  // summed over threads: runtime evaluation
    uint64_t evaluations = 0;
    uint64_t volumeEvaluations = 0;  // volume queries at inserted objects (not in evaluations)
    uint64_t outsideGrid = 0, emptyVoxel = 0, invalidInput = 0;  // per-point flags
};

// Radiance of a batch of first hits: positions, shading normals and directions towards the camera
// (interleaved xyz, `count` each) -> rgb (interleaved) and a per-point flag (NRAD_POINT_*). Called from
// worker threads concurrently. Returns NRAD_OK or the failure to report.
using FirstHitEvaluator = std::function<NradStatus(size_t count, const float* positions, const float* normals,
                                                   const float* directions, float* rgb, uint8_t* flags)>;

// The light in the volume at a batch of receivers that were not in the bake (Scene::insertedObjects): positions and
// shading normals (interleaved xyz) -> D(x, n) = E(x, n) / pi (rgb interleaved) and a per-point flag.
using VolumeEvaluator = std::function<NradStatus(size_t count, const float* positions, const float* normals, float* rgb,
                                                 uint8_t* flags)>;

// The volume's glossy response at such receivers (nrad/eval.h's glossy query): positions, shading normals and
// directions towards the camera -> the prefiltered light (rgb interleaved) and a per-point flag.
using GlossyEvaluator = std::function<NradStatus(size_t count, const float* positions, const float* normals, const float* directions,
                                                 float* rgb, uint8_t* flags)>;

// Renders with primary visibility only, radiance at the first hit from `evaluate`, shaded by the contract of
// nrad/eval.h (contentFlags: format::kFlag*; with kFlagScatteredRadiance the hit's own emission towards the
// camera is added): tile by tile, each tile's hits in one batch. The same sample positions as
// renderThroughAsset, so any two evaluators render the same hits. With `volume`, hits on inserted objects are
// shaded from it by eval::shadeVolume (one more batch per tile), and with `glossy` too by eval::shadeVolumeGlossy
// (another); without, like the bake's surfaces.
NradStatus renderFirstHit(const Scene& scene, const Accel& accel, const FirstHitEvaluator& evaluate, uint32_t contentFlags,
                          const Camera& camera, const RenderSettings& settings, Image& image,
                          NeuralRenderStats* stats = nullptr, const std::function<void(double)>& progress = {},
                          const VolumeEvaluator& volume = {}, const GlossyEvaluator& glossy = {});

// The asset's contentFlags decide the shading; inserted objects are shaded through its volume query
// (nradEvaluateVolumeBatch) when it has volume networks, and its glossy response (nradEvaluateVolumeGlossyBatch)
// when it has that too. Fails with the runtime's status if evaluation fails.
NradStatus renderThroughAsset(const Scene& scene, const Accel& accel, NradAsset asset, const Camera& camera,
                              const RenderSettings& settings, Image& image, NeuralRenderStats* stats = nullptr,
                              const std::function<void(double)>& progress = {});

}  // namespace nrad
