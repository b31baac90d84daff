// PathTracer: unbiased Monte Carlo estimates of L(h(o, d), -d), the radiance arriving along a ray.
// Next event estimation over all lights (picked by power, uniformly or by a learned distribution; see
// light_selection.h) combined with BSDF sampling by multiple
// importance sampling (power heuristic), Russian roulette, an optional maximum path length, no clamping.
// Images are rendered over tiles with TBB; every sample depends only on (pixel, sample index, seed), so
// the image is byte-identical for any number of threads.
#pragma once

#include <atomic>
#include <cstdint>
#include <functional>
#include <memory>
#include <vector>

#include <glm/glm.hpp>

#include "baker/render/accel.h"
#include "baker/render/image_io.h"
#include "baker/lights/light_sampler.h"
#include "baker/lights/light_selection.h"
#include "baker/render/sampler.h"
#include "baker/render/surface.h"
#include "baker/scene/scene.h"

namespace nrad {

struct RayCounters {
    uint64_t primary = 0;  // camera rays
    uint64_t extension = 0;  // closest-hit rays after the first
    uint64_t shadow = 0;  // occlusion rays
    uint64_t nonFiniteSamples = 0;  // samples dropped because the estimate was NaN or Inf
    uint64_t total() const { return primary + extension + shadow; }
    RayCounters& operator+=(const RayCounters& o) {
        primary += o.primary;
        extension += o.extension;
        shadow += o.shadow;
        nonFiniteSamples += o.nonFiniteSamples;
        return *this;
    }
};

// Paths a batch of the batched tracer traces together (renders and training estimates).
constexpr int kBatchSize = 256;

struct RenderSettings {
    int width = 512;
    int height = 512;
    int spp = 64;
    int maxDepth = 0;  // maximum number of path segments (1 = emission seen directly); 0 = unbounded
    uint32_t seed = 0;
    int tileSize = 16;
    // Paths traced together (a wavefront: one vertex of every path, then their shadow rays and their extension
    // rays as Embree streams, which give the single-ray results bit for bit). 1 traces one path at a time (the
    // plain reference the batched tracer is tested against).
    int batchSize = kBatchSize;
    // Batches trace their camera rays as a coherent stream (Embree's packet kernels, faster on large levels:
    // docs/design.md). The packet kernels differ from the single-ray ones in the last bits of rare hits, which
    // depend on the packet's other rays: the image is deterministic (the same for any number of threads) but
    // differs from batches of another size in a few pixels. false: the same image, bit for bit, for every batch
    // size.
    bool coherentCameraRays = true;
};

struct RenderStats {
    double seconds = 0.0;
    uint64_t samples = 0;
    RayCounters rays;
    double raysPerSecond() const { return seconds > 0.0 ? double(rays.total()) / seconds : 0.0; }
};

// Per-path extras of light selection: where to append the training records of the vertices at which the
// selection network was evaluated, and the group chosen at the first vertex (-1: none), for pictures.
struct NeeTrace {
    std::vector<NeeRecord>* records = nullptr;
    int firstLight = -1;
};

// What stands in for the rest of a path where it is cut (training within the integral equation, paper Sec. 3):
// the radiance the surface at an interaction scatters towards its wo, without its own emission.
using ScatteredRadiance = std::function<glm::vec3(const SurfaceInteraction&)>;

// One path of a batch (PathTracer::estimate): from the interaction *si, with Sampler(stream, index).
struct PathStart {
    const SurfaceInteraction* si = nullptr;
    uint32_t stream = 0;
    uint32_t index = 0;
};

// The shadow ray that tests whether light sample `ls` reaches the surface point `si`: origin, unit direction
// and the interval [tnear, tfar) in which an occluder blocks it (none if tfar <= tnear). Robust at grazing
// angles and at any scene scale or distance from the origin (issue 12).
void shadowRay(const SurfaceInteraction& si, const LightSample& ls, glm::vec3& origin, glm::vec3& direction,
               float& tnear, float& tfar);

class PathTracer {
public:
    // selector: light selection for NEE; nullptr picks lights by power.
    PathTracer(const Scene& scene, const Accel& accel, const LightSampler& lights,
               const LightSelector* selector = nullptr)
        : scene_(scene), accel_(accel), lights_(lights),
          powerSelector_(selector ? nullptr : std::make_shared<const LightSelector>(lights, scene.bounds, NeeSettings{})),
          selector_(selector ? selector : powerSelector_.get()) {}

    // Mixed lighting: leave out the direct light (next event estimation at the first vertex) of the lights the
    // engine draws at run time (PunctualLight::runtimeDirect), so estimates hold only their indirect light.
    // For training targets; references keep everything.
    void setExcludeEngineDrawnDirect(bool exclude) { excludeEngineDrawn_ = exclude; }

    // Russian roulette from the third segment on keeps a path with probability min(1, throughput / t) and
    // divides the throughput by it. t = 1 (renders): a path's weight stays near 1 and its length is geometric
    // in the albedo. A smaller t (training targets) follows every path deterministically until its
    // throughput falls below t, so the long multiple-bounce part of bright closed scenes is summed instead of
    // sampled (lower variance per path, longer paths): unbiased either way.
    void setRouletteThreshold(float t) { rouletteThreshold_ = t; }

    // One estimate of the radiance arriving at `origin` from direction `direction` (i.e. leaving the
    // first surface hit towards origin). maxDepth counts path segments including this first ray.
    // If `record` is given, every ray traced is appended to it (benchmarks).
    glm::vec3 radiance(glm::vec3 origin, glm::vec3 direction, Sampler& sampler, int maxDepth, RayCounters& counters,
                       std::vector<RecordedRay>* record = nullptr, NeeTrace* nee = nullptr) const;

    // One estimate of L(x, wo) at an existing surface interaction (emission included), with the same
    // integrator; si counts as reached by one segment, so maxDepth means the same as for camera paths.
    glm::vec3 outgoingRadiance(const SurfaceInteraction& si, Sampler& sampler, int maxDepth, RayCounters& counters,
                               NeeTrace* nee = nullptr) const;

    // One estimate of the scattered radiance L(x, wo) - Le(x, wo) at si from `bounces` (>= 1) BSDF bounces with
    // next event estimation and MIS, the path cut at the vertex the last bounce reaches: its emission (MIS
    // weighted as usual) plus `tail` there (plus, for training targets with engine-drawn lights excluded, those
    // lights' direct light there, which the tail does not hold). A vertex with a sharp lobe (metal or glass of
    // roughness below 0.5) is bounced through instead, up to 4 more bounces. No Russian roulette before the cut.
    glm::vec3 scatteredRadiance(const SurfaceInteraction& si, Sampler& sampler, int bounces, const ScatteredRadiance& tail,
                                RayCounters& counters) const;

    // outgoingRadiance (tail == nullptr, with maxDepth) or scatteredRadiance (with tail and bounces) for many
    // paths, traced in batches as render() traces camera paths: out[i] has the bits the one-path call gives
    // for starts[i].
    void estimate(const PathStart* starts, size_t n, int maxDepth, const ScatteredRadiance* tail, int bounces,
                  RayCounters& counters, glm::vec3* out) const;

    // Whether a viewer can ever ask for the radiance leaving si towards si.wo: false when the ray from si.p
    // along wo first meets the back of an opaque single-sided surface, i.e. the viewer would stand inside a
    // closed object or behind a surface lying on this one (the floor under a box, the ceiling 0.1 mm above a
    // light panel). Surfaces seen through (transmission, alpha blending) hide nothing. One ray.
    bool viewable(const SurfaceInteraction& si) const;

    // Renders an image; progress(fraction) is called from worker threads as tiles finish.
    Image render(const Camera& camera, const RenderSettings& settings, RenderStats* stats = nullptr,
                 const std::function<void(double)>& progress = {}) const;

    // The camera rays and all secondary rays of the first `maxSamples` samples of a render, in the order the
    // tracer issued them (benchmarks).
    std::vector<RecordedRay> recordRays(const Camera& camera, const RenderSettings& settings) const;

private:
    struct Path;  // one path's state between its vertices (path_tracer.cpp)
    struct BatchScratch;
    struct TileRender;  // render()'s tiles
    // The parts of one path vertex, shared by the one-path tracer (trace) and the batched one (traceBatch).
    // scatterBegin: emission at p.si (MIS-weighted), the cut, the vertex's sample points (u: three 2D points,
    // nullptr to draw them from p's sampler) and the light sample; false if the path ends here. shade: the
    // BSDF's part (the light sample's value and pdf, the BSDF sample). scatterEnd: next event estimation's
    // shadow query and contribution, the throughput and Russian roulette; returns whether the path goes on
    // along p.extension. finishShadow: the pending contribution, unless its shadow ray is blocked. arrive:
    // the extension ray's hit (false: it left the scene, whose light is added).
    // With `quad` (the batched tracer), scatterBegin leaves the light sample to scatterBatch where it picks a quad
    // light without texture at a vertex without transmission: it returns kQuadLanes with the pick in *quad.
    enum Next { kEnd, kShade, kQuadLanes };
    Next scatterBegin(Path& p, const glm::vec2* u, int maxDepth, NeeTrace* nee, const ScatteredRadiance* tail,
                      LightSampler::QuadPick* quad = nullptr) const;
    static void shade(Path& p);
    // shade() for the paths in scratch.shading.
    static void shadeBatch(Path* paths, BatchScratch& scratch);
    // The light sample, shade() and scatterEnd for the paths in scratch.quadPaths (their picks in
    // scratch.quadPicks; whether each goes on in scratch.quadMore), in SIMD lanes (scatter_lanes.h).
    void scatterBatch(Path* paths, BatchScratch& scratch, RayCounters& counters) const;
    bool scatterEnd(Path& p, RayCounters& counters, std::vector<RecordedRay>* record) const;
    // scatterEnd's second half: the BSDF sample continues the path (throughput, Russian roulette).
    bool extend(Path& p, RayCounters& counters, std::vector<RecordedRay>* record) const;
    void finishShadow(Path& p, bool blocked, NeeTrace* nee) const;
    bool arrive(Path& p, const Hit& hit) const;
    // Runs paths[0..n) (each with its interaction, sampler and selection buffers set) to their ends.
    void traceBatch(Path* paths, size_t n, int maxDepth, RayCounters& counters, BatchScratch& scratch, int cutDepth = 0,
                    const ScatteredRadiance* tail = nullptr) const;

    // cutDepth > 0: the path ends at the vertex reached by that many bounces with `tail` (scatteredRadiance).
    glm::vec3 trace(SurfaceInteraction si, Sampler& sampler, int maxDepth, RayCounters& counters,
                    std::vector<RecordedRay>* record, NeeTrace* nee, int cutDepth = 0,
                    const ScatteredRadiance* tail = nullptr) const;

    const Scene& scene_;
    const Accel& accel_;
    const LightSampler& lights_;
    std::shared_ptr<const LightSelector> powerSelector_;  // without a selector of the caller's
    const LightSelector* selector_;
    float rouletteThreshold_ = 1.0f;
    bool excludeEngineDrawn_ = false;
};

// The direct light at si of the lights the engine draws at run time (delta lights, exact: f Li cos times
// visibility through one shadow ray each), as the engine would add it to the asset's indirect light.
glm::vec3 engineDrawnDirect(const Scene& scene, const Accel& accel, const SurfaceInteraction& si);

}  // namespace nrad
