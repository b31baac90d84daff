// Online rendering (paper Sec. 4, Fig. "renderImage"). Training happens in rounds of batchesPerRound x 64
// path samples; between rounds the light-selection network takes a training step on the contributions the
// round recorded. Paths visit the pixels in a fixed shuffled order, one pass of every pixel per sample per
// pixel, so snapshots at 1, 2, 4, ... spp are exactly what a run with that many samples gives.
//
// Learned mode with NeeSettings::warmupSteps > 0 (the default): training rounds of camera paths (their own
// sampler streams, each round sized to give trainBatches x 64 useful records) first take that many Adam
// steps, the learning rate decaying linearly to zero, then the network is frozen and the image rendered
// pass by pass. With warmupSteps = 0 (the paper's variant) the image itself is rendered in training rounds
// and keeps every sample; the distribution then changes between a pixel's samples, which costs the pick
// dimension its per-pixel stratification (docs/results.md measures both).
//
// Every image sample uses the same sampler (pixel, sample index, seed) as PathTracer::render, and the
// network only changes between rounds in a fixed order: the image is byte-identical for any number of
// threads.
#pragma once

#include <cstdint>
#include <functional>
#include <vector>

#include "baker/render/camera.h"
#include "baker/lights/light_selection.h"
#include "baker/render/path_tracer.h"

namespace nrad {

struct OnlineSnapshot {
    int spp = 0;
    double seconds = 0.0;  // wall time from the start of the render, training included
    Image image;
};

struct OnlineRenderStats {
    RenderStats render;  // seconds = whole render incl. warm-up and training; rays and samples: the image's
    double trainingSeconds = 0.0;  // Adam steps (warm-up included)
    double warmupSeconds = 0.0;  // warm-up paths and their training
    uint64_t warmupPaths = 0;
    uint64_t rounds = 0;
    uint64_t records = 0;  // contributions recorded for training
    uint64_t trainingSteps = 0;
};

struct OnlineRenderResult {
    Image image;
    std::vector<OnlineSnapshot> snapshots;
    std::vector<int32_t> firstLight;  // per pixel: group chosen at the first vertex of its last sample, -1 none
    OnlineRenderStats stats;
};

// Renders with `tracer` (whose selector may be `trainee`, trained in learned mode; after a warm-up the
// trainee is left frozen: settings().train = false).
// snapshotSpp: sample counts at which to keep a copy of the image (and the time it took).
OnlineRenderResult renderOnline(const PathTracer& tracer, LightSelector* trainee, const Camera& camera,
                                const RenderSettings& settings, const std::vector<int>& snapshotSpp = {},
                                const std::function<void(double)>& progress = {});

// Trains `trainee` (learned mode) on paths that start at given surface points, as the baker's training paths
// do: `paths` path samples in rounds (learning rate decaying to zero, as for a render's warm-up); start(k, stream, index) returns the interaction path k leaves from and
// sets its sampler's stream and index. The estimates themselves are not kept.
struct WarmupStats {
    double seconds = 0.0;
    uint64_t paths = 0, records = 0, trainingSteps = 0;
    RayCounters rays;
};
WarmupStats trainSelectorOnPaths(const PathTracer& tracer, LightSelector& trainee, uint64_t paths, int maxDepth,
                                 const std::function<SurfaceInteraction(uint64_t, uint32_t&, uint32_t&)>& start);

// A colour per light group (index -1: black), for pictures of the chosen light.
glm::vec3 lightGroupColor(int group);

}  // namespace nrad
