#include "baker/bake/volume_samples.h"

#include <atomic>
#include <chrono>
#include <cmath>
#include <mutex>

#include <tbb/parallel_for.h>

#include "baker/bake/training_samples.h"
#include "baker/nn/random.h"
#include "baker/util/maths.h"

namespace nrad {
namespace {

glm::vec3 uniformDirection(SplitMix64& r) {
    const float z = 1.0f - 2.0f * r.uniform(), phi = 2.0f * kPi * r.uniform();
    const float s = std::sqrt(std::max(0.0f, 1.0f - z * z));
    return {s * std::cos(phi), s * std::sin(phi), z};
}

// The world box of cell c.
void cellBox(const eval::Partition& partition, uint64_t c, glm::vec3& lo, glm::vec3& hi) {
    const format::Grid& g = partition.grid;
    uint32_t a[3], b[3];
    if (partition.tree.empty()) {
        const uint64_t x = c % g.dims[0], y = (c / g.dims[0]) % g.dims[1], z = c / (uint64_t(g.dims[0]) * g.dims[1]);
        const uint64_t coord[3] = {x, y, z};
        for (int k = 0; k < 3; ++k) a[k] = uint32_t(coord[k]), b[k] = uint32_t(coord[k]) + 1;
    } else {
        for (int k = 0; k < 3; ++k) a[k] = partition.boxes[c].lo[k], b[k] = partition.boxes[c].hi[k];
    }
    for (int k = 0; k < 3; ++k) {
        lo[k] = g.lower[k] + float(a[k]) / partition.factor[k];
        hi[k] = g.lower[k] + float(b[k]) / partition.factor[k];
    }
}

}  // namespace

SurfaceInteraction receiverAt(const glm::vec3& p, const glm::vec3& n) {
    SurfaceInteraction si;
    si.p = p;
    si.ng = si.ns = si.wo = n;
    si.frontFace = true;
    si.bsdf.baseColor = glm::vec3(1.0f);
    si.bsdf.metallic = 0.0f;
    si.bsdf.roughness = 1.0f;
    si.bsdf.specular = 0.0f;  // no specular layer: Lambertian, albedo 1
    si.bsdf.transmission = 0.0f;
    si.emission = glm::vec3(0.0f);
    si.margin = 0.0f;
    return si;
}

SurfaceInteraction glossyReceiverAt(const glm::vec3& p, const glm::vec3& n, const glm::vec3& v) {
    SurfaceInteraction si = receiverAt(p, n);
    si.wo = v;
    si.bsdf.metallic = 1.0f;
    si.bsdf.roughness = eval::kGlossyRoughness;
    si.bsdf.specular = 1.0f;
    return si;
}

std::vector<TrainingSample> generateVolumeSamples(const PathTracer& tracer, const eval::Partition& partition,
                                                  const VolumeSettings& settings, uint32_t seed, int maxDepth, VolumeStats& stats,
                                                  bool glossy) {
    const auto t0 = std::chrono::steady_clock::now();
    const uint64_t cells = partition.cells;
    const uint32_t per = settings.pointsPerCell, paths = std::max(1u, settings.paths);
    std::vector<std::vector<TrainingSample>> byCell(cells);  // what a cell keeps (memory: the kept points only)
    std::atomic<uint64_t> inside{0}, rays{0}, noisyPoints{0}, extraPaths{0};
    SampleSettings noisy;  // the bound of noisyExtraPaths, counted on from the volume's paths
    noisy.paths = paths;
    noisy.extraPathsFactor = settings.extraPathsFactor;
    noisy.noisyRelativeError = settings.noisyRelativeError;
    // The points of a chunk traced together: a few tracer batches of paths at a time, whatever N and the paths.
    const size_t chunk = std::max<size_t>(1, size_t(4 * kBatchSize) / paths);
    tbb::parallel_for(tbb::blocked_range<uint64_t>(0, cells, 1), [&](const tbb::blocked_range<uint64_t>& range) {
        RayCounters counters;
        std::vector<SurfaceInteraction> starts;
        std::vector<PathStart> batch;
        std::vector<glm::vec3> estimates;
        std::vector<uint32_t> extraOf;
        for (uint64_t c = range.begin(); c != range.end(); ++c) {
            glm::vec3 lo, hi;
            cellBox(partition, c, lo, hi);
            for (uint32_t first = 0; first < per; first += uint32_t(chunk)) {
                const uint32_t last = uint32_t(std::min<uint64_t>(per, uint64_t(first) + chunk));
                starts.clear();
                std::vector<uint32_t> index;
                for (uint32_t i = first; i < last; ++i) {
                    // Every point from (seed, cell, index) alone: the same whatever the threads.
                    SplitMix64 r(SplitMix64(SplitMix64(uint64_t(seed) ^ 0x766f6c756d65ull).next() + c).next() + i);
                    const glm::vec3 p = lo + (hi - lo) * glm::vec3(r.uniform(), r.uniform(), r.uniform());
                    bool out = true;
                    for (int d = 0; d < 2 && out; ++d) {
                        out = tracer.viewable(receiverAt(p, uniformDirection(r)));
                        ++counters.extension;
                    }
                    if (!out) {
                        ++inside;
                        continue;
                    }
                    const glm::vec3 n = uniformDirection(r);
                    if (glossy) {  // its own normal and viewer, after every draw the diffuse samples make
                        SplitMix64 g(r.next() ^ 0x676c6f7373ull);
                        const glm::vec3 ng = uniformDirection(g);
                        glm::vec3 v = uniformDirection(g);
                        if (glm::dot(v, ng) < 0.0f) v = -v;
                        starts.push_back(glossyReceiverAt(p, ng, v));
                    } else {
                        starts.push_back(receiverAt(p, n));
                    }
                    index.push_back(i);
                }
                batch.clear();
                for (size_t k = 0; k < starts.size(); ++k)
                    for (uint32_t j = 0; j < paths; ++j)
                        batch.push_back({&starts[k], uint32_t((c * per + index[k]) * 0x9e3779b1u) ^ seed ^ (glossy ? 0x2545f491u : 0x5f3759dfu), j});
                estimates.resize(batch.size());
                if (!batch.empty()) tracer.estimate(batch.data(), batch.size(), maxDepth, nullptr, 1, counters, estimates.data());
                // Noisy targets: the paths that bring the mean's relative standard error to the bound, numbered on
                // from `paths` (noisyExtraPaths, as the surfaces' points), traced together.
                extraOf.assign(starts.size(), 0);
                const size_t firstExtra = batch.size();
                for (size_t k = 0; k < starts.size() && noisy.extraPathsFactor > 1 && paths > 1; ++k) {
                    extraOf[k] = noisyExtraPaths(&estimates[k * paths], paths, noisy);
                    for (uint32_t j = 0; j < extraOf[k]; ++j) batch.push_back({&starts[k], batch[k * paths].stream, paths + j});
                }
                if (batch.size() > firstExtra) {
                    estimates.resize(batch.size());
                    tracer.estimate(batch.data() + firstExtra, batch.size() - firstExtra, maxDepth, nullptr, 1, counters,
                                    estimates.data() + firstExtra);
                }
                size_t extraAt = firstExtra;
                for (size_t k = 0; k < starts.size(); ++k) {
                    glm::dvec3 sum(0.0);
                    uint32_t n = 0;
                    auto add = [&](const glm::vec3& L) {
                        if (!(std::isfinite(L.x) && std::isfinite(L.y) && std::isfinite(L.z))) return;
                        sum += glm::dvec3(L);
                        ++n;
                    };
                    for (uint32_t j = 0; j < paths; ++j) add(estimates[k * paths + j]);
                    for (uint32_t j = 0; j < extraOf[k]; ++j) add(estimates[extraAt + j]);
                    extraAt += extraOf[k];
                    if (extraOf[k] > 0) {
                        ++noisyPoints;
                        extraPaths += extraOf[k];
                    }
                    if (n == 0) continue;
                    TrainingSample t;
                    t.position = starts[k].p;
                    t.normal = starts[k].ns;
                    t.wo = starts[k].wo;
                    t.radiance = glm::vec3(sum / double(n));
                    if (glossy) t.radiance /= eval::glossyAlbedo(glm::dot(t.normal, t.wo));
                    t.voxel = uint32_t(c);
                    t.reflectance = glm::vec3(1.0f);
                    byCell[c].push_back(t);
                }
            }
        }
        rays += counters.total();
    });
    std::vector<TrainingSample> out;
    size_t kept = 0;
    for (const std::vector<TrainingSample>& v : byCell) kept += v.size();
    out.reserve(kept);
    for (std::vector<TrainingSample>& v : byCell) {
        out.insert(out.end(), v.begin(), v.end());
        std::vector<TrainingSample>().swap(v);
    }
    stats.tried = cells * per;
    stats.inside = inside;
    stats.rays = rays;
    stats.noisyPoints = noisyPoints;
    stats.extraPaths = extraPaths;
    stats.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    return out;
}

}  // namespace nrad
