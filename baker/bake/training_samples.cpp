// Training-sample generation: area-uniform points on clipped surface pieces, path-traced radiance.
#include "baker/bake/training_samples.h"

#include <algorithm>
#include <atomic>
#include <cmath>
#include <mutex>

#include <tbb/parallel_for.h>

#include "baker/render/online_render.h"
#include "baker/render/surface.h"

namespace nrad {

namespace {

// Streams of the sampler, one per purpose, so the point sequence does not depend on the path count.
constexpr uint32_t kPointStream = 0x706f696eu;  // "poin"
constexpr uint32_t kFloorStream = 0x666c6f6fu;  // "floo"
constexpr uint32_t kPathStream = 0x70617468u;  // "path"
constexpr uint32_t kWarmupStream = 0x6e656521u;  // "nee!"

size_t pickByCdf(const std::vector<double>& cdf, double u) {
    size_t i = size_t(std::upper_bound(cdf.begin(), cdf.end(), u * cdf.back()) - cdf.begin());
    return std::min(i, cdf.size() - 1);
}

struct PointRequest {
    uint32_t piece;
    glm::vec2 uPoint;
    glm::vec2 uDirection;
    uint32_t pathStream;
};

}  // namespace

std::vector<TrainingSample> generateTrainingSamples(const Scene& scene, const PathTracer& tracer, const VoxelGrid& grid,
                                                    const SurfacePieces& pieces, const SampleSettings& settings,
                                                    SampleStats& stats, const std::function<void(double)>& progress,
                                                    LightSelector* trainee, const TargetEstimator& estimator) {
    stats = SampleStats{};
    stats.perVoxel.assign(grid.voxelCount(), 0);
    std::vector<TrainingSample> samples;
    if (pieces.pieces().empty()) return samples;

    // Pass 1: points uniform by area over the whole surface. Pass 2: the floor, per voxel. Both are decided
    // up front (cheap) so that the expensive path tracing runs as one parallel loop.
    std::vector<PointRequest> requests;
    std::vector<double> cdf;
    cdf.reserve(pieces.pieces().size());
    double acc = 0.0;
    for (const SurfacePiece& p : pieces.pieces()) cdf.push_back(acc += p.area);
    uint32_t pointStream = hashCombine(settings.seed, kPointStream);
    std::vector<uint32_t> count(grid.voxelCount(), 0);
    requests.resize(settings.points);
    tbb::parallel_for(tbb::blocked_range<uint32_t>(0, settings.points, 1024), [&](const tbb::blocked_range<uint32_t>& range) {
        for (uint32_t k = range.begin(); k != range.end(); ++k) {
            const uint32_t i = settings.firstPoint + k;
            Sampler s(pointStream, i);
            float uPiece = s.get1D();
            requests[k] = {uint32_t(pickByCdf(cdf, uPiece)), s.get2D(), s.get2D(), hashCombine(hashCombine(settings.seed, kPathStream), i)};
        }
    });
    // The point, its outgoing direction and the interaction the paths start from.
    auto startOf = [&](const PointRequest& r, glm::vec3& p, glm::vec3& wo) {
        const SurfacePiece& piece = pieces.pieces()[r.piece];
        float b1, b2;
        p = pieces.samplePiece(piece, r.uPoint, b1, b2);
        // The hemisphere around the winding-side shading normal at the point.
        const glm::uvec3& tri = scene.mesh.triangles[piece.triangle];
        glm::vec3 ng = scene.mesh.geometricNormal(piece.triangle);
        glm::vec3 n = (1.0f - b1 - b2) * scene.mesh.normals[tri.x] + b1 * scene.mesh.normals[tri.y] + b2 * scene.mesh.normals[tri.z];
        float nl = glm::length(n);
        n = (nl > 1e-6f && std::isfinite(nl)) ? n / nl : ng;
        if (glm::dot(n, ng) < 0.0f) n = -n;
        float z = r.uDirection.x, rad = std::sqrt(std::max(0.0f, 1.0f - z * z)), phi = 2.0f * kPi * r.uDirection.y;
        Frame frame = Frame::fromNormal(n);
        wo = glm::normalize(frame.toWorld(glm::vec3(rad * std::cos(phi), rad * std::sin(phi), z)));
        Hit hit;
        hit.t = 0.0f;
        hit.triangle = piece.triangle;
        hit.u = b1;
        hit.v = b2;
        SurfaceInteraction si = makeInteraction(scene, hit, -wo);
        si.p = p;  // the exact sampled point (inside its voxel)
        return si;
    };

    // Points no viewer sees from their direction are dropped before anything is traced from them, and the
    // floor counts only the points that remain.
    auto hiddenFrom = [&](const PointRequest& r) {
        if (!settings.dropHidden) return false;
        glm::vec3 p, wo;
        return !tracer.viewable(startOf(r, p, wo));
    };
    std::vector<uint8_t> hidden(requests.size(), 0);
    tbb::parallel_for(tbb::blocked_range<size_t>(0, requests.size(), 256), [&](const tbb::blocked_range<size_t>& range) {
        for (size_t i = range.begin(); i != range.end(); ++i) hidden[i] = hiddenFrom(requests[i]);
    });
    for (size_t i = 0; i < requests.size(); ++i) {
        if (hidden[i]) {
            ++stats.hiddenSamples;
            continue;
        }
        ++count[pieces.pieces()[requests[i].piece].voxel];
    }
    stats.points = settings.points;
    // The floor, voxel by voxel (in parallel, each voxel from its own stream): candidates from the voxel's own
    // surface until it has the floor's number of points a viewer sees, or 16 times the floor was tried (a
    // voxel whose surface is all hidden keeps what it has).
    std::vector<std::vector<PointRequest>> floorOf(grid.voxelCount());
    tbb::parallel_for(uint32_t(0), grid.voxelCount(), [&](uint32_t v) {
        const std::vector<uint32_t>& own = pieces.piecesOf(v);
        if (own.empty() || count[v] >= settings.minSamplesPerVoxel) return;
        std::vector<double> vcdf;
        double vacc = 0.0;
        for (uint32_t p : own) vcdf.push_back(vacc += pieces.pieces()[p].area);
        uint32_t stream = hashCombine(hashCombine(settings.seed, kFloorStream), v);
        if (settings.generation != 0) stream = hashCombine(stream, settings.generation);
        const uint32_t needed = settings.minSamplesPerVoxel - count[v];
        for (uint32_t j = 0; j < 16 * settings.minSamplesPerVoxel && floorOf[v].size() < needed; ++j) {
            Sampler s(stream, j);
            float uPiece = s.get1D();
            uint32_t pathStream = hashCombine(hashCombine(hashCombine(settings.seed, kPathStream), 0x80000000u | v), j);
            if (settings.generation != 0) pathStream = hashCombine(pathStream, settings.generation);
            PointRequest r{own[pickByCdf(vcdf, uPiece)], s.get2D(), s.get2D(), pathStream};
            if (!hiddenFrom(r)) floorOf[v].push_back(r);
        }
    });
    for (const std::vector<PointRequest>& f : floorOf) {
        requests.insert(requests.end(), f.begin(), f.end());
        stats.floorPoints += f.size();
    }
    hidden.resize(requests.size(), 0);

    // Learned light selection: train the network on paths from these points first, then keep it fixed.
    if (trainee && trainee->mode() == NeeMode::Learned && settings.neeWarmupPaths > 0 && !requests.empty()) {
        const uint64_t n = requests.size();
        WarmupStats w = trainSelectorOnPaths(tracer, *trainee, settings.neeWarmupPaths, settings.maxDepth,
                                             [&](uint64_t k, uint32_t& stream, uint32_t& index) {
                                                 const PointRequest& r = requests[size_t(k % n)];
                                                 stream = hashCombine(r.pathStream, kWarmupStream);
                                                 index = uint32_t(k / n);
                                                 glm::vec3 p, wo;
                                                 return startOf(r, p, wo);
                                             });
        trainee->setTraining(false);
        stats.neeWarmupPaths = w.paths;
        stats.neeTrainingSteps = w.trainingSteps;
        stats.neeWarmupSeconds = w.seconds;
        stats.rays += w.rays;
    }

    std::vector<TrainingSample> out(requests.size());
    std::vector<uint8_t> valid(requests.size(), 0);
    std::atomic<size_t> done{0};
    std::mutex statsMutex;
    // Ranges of enough points for a few hundred paths (the tracer's batches); the samples do not depend on them.
    const size_t grain = std::max<size_t>(8, size_t(kBatchSize) / std::max<uint32_t>(1, settings.paths));
    tbb::parallel_for(tbb::blocked_range<size_t>(0, requests.size(), grain), [&](const tbb::blocked_range<size_t>& range) {
        RayCounters counters;
        uint64_t nonFinite = 0, noisy = 0;
        // The range's points, then all their paths traced together (PathTracer::estimate, in batches).
        std::vector<size_t> points;
        std::vector<SurfaceInteraction> starts;
        std::vector<glm::vec3> pointWo, pointP;
        for (size_t i = range.begin(); i != range.end(); ++i) {
            const PointRequest& r = requests[i];
            const SurfacePiece& piece = pieces.pieces()[r.piece];
            glm::vec3 p, wo;
            SurfaceInteraction si = startOf(r, p, wo);
            // A point in an alpha cutout's hole is no surface: dropped (counted in droppedSamples).
            if (si.material && si.material->alphaMode == Material::AlphaMode::Mask) {
                float b1, b2;
                pieces.samplePiece(piece, r.uPoint, b1, b2);
                if (surfaceOpacity(scene, piece.triangle, b1, b2) <= 0.0f) continue;
            }
            if (hidden[i]) continue;
            points.push_back(i);
            starts.push_back(si);
            pointP.push_back(p);
            pointWo.push_back(wo);
        }
        std::vector<PathStart> paths;
        paths.reserve(points.size() * settings.paths);
        for (size_t k = 0; k < points.size(); ++k)
            for (uint32_t j = 0; j < settings.paths; ++j) paths.push_back({&starts[k], requests[points[k]].pathStream, j});
        std::vector<glm::vec3> estimates(paths.size());
        tracer.estimate(paths.data(), paths.size(), settings.maxDepth, estimator.tail, estimator.bounces, counters,
                        estimates.data());
        // Noisy targets: points whose mean's relative standard error is above the bound get more paths,
        // traced together as well (paths numbered on from settings.paths).
        std::vector<uint32_t> extraOf(points.size(), 0);
        const bool adaptive = !estimator.tail && settings.extraPathsFactor > 1 && settings.paths > 1;
        if (adaptive) {
            std::vector<PathStart> more;
            const uint32_t extra = (settings.extraPathsFactor - 1) * settings.paths;
            for (size_t k = 0; k < points.size(); ++k) {
                double s1 = 0.0, s2 = 0.0;
                uint32_t n = 0;
                for (uint32_t j = 0; j < settings.paths; ++j) {
                    const glm::vec3& L = estimates[k * settings.paths + j];
                    if (!(std::isfinite(L.x) && std::isfinite(L.y) && std::isfinite(L.z))) continue;
                    const double l = 0.2126 * L.x + 0.7152 * L.y + 0.0722 * L.z;
                    s1 += l;
                    s2 += l * l;
                    ++n;
                }
                if (n < 2 || !(s1 > 0.0)) continue;
                const double mean = s1 / n, var = std::max(0.0, s2 / n - mean * mean) * n / (n - 1);
                if (std::sqrt(var / n) <= double(settings.noisyRelativeError) * mean) continue;
                extraOf[k] = extra;
                for (uint32_t j = 0; j < extra; ++j) more.push_back({&starts[k], requests[points[k]].pathStream, settings.paths + j});
            }
            if (!more.empty()) {
                const size_t at = estimates.size();
                estimates.resize(at + more.size());
                tracer.estimate(more.data(), more.size(), settings.maxDepth, estimator.tail, estimator.bounces, counters,
                                estimates.data() + at);
            }
        }
        size_t extraAt = points.size() * settings.paths;
        for (size_t k = 0; k < points.size(); ++k) {
            const size_t i = points[k];
            const SurfacePiece& piece = pieces.pieces()[requests[i].piece];
            const SurfaceInteraction& si = starts[k];
            const glm::vec3 &p = pointP[k], &wo = pointWo[k];
            glm::dvec3 sum(0.0);
            uint32_t finite = 0;
            auto add = [&](const glm::vec3& L) {
                if (std::isfinite(L.x) && std::isfinite(L.y) && std::isfinite(L.z)) {
                    sum += glm::dvec3(L);
                    ++finite;
                } else {
                    ++nonFinite;
                }
            };
            for (uint32_t j = 0; j < settings.paths; ++j) add(estimates[k * settings.paths + j]);
            for (uint32_t j = 0; j < extraOf[k]; ++j) add(estimates[extraAt + j]);
            extraAt += extraOf[k];
            if (extraOf[k] > 0) ++noisy;
            if (finite > 0) {
                TrainingSample& t = out[i];
                t.position = p;
                t.normal = si.ns;
                t.wo = wo;
                // The target is the radiance the point scatters, L - Le: its own emission is exact and is
                // added back by whoever shades (nrad/eval.h, shade()), so no network has to draw an
                // emitter's edge. Rounding can leave -1 ulp: clamped.
                const glm::vec3 own = estimator.tail ? glm::vec3(0.0f) : si.emission;  // the tail's estimates have none
                t.radiance = glm::max(glm::vec3(sum / double(finite)) - own, glm::vec3(0.0f));
                float refl[3];
                eval::reflectance(shadingSurface(si), glm::dot(si.ns, wo), refl);
                t.reflectance = glm::vec3(refl[0], refl[1], refl[2]);
                // The voxel the runtime will look up for p (the format's rule): a point on a border plane
                // belongs to the voxel above it, whichever piece it was sampled from.
                int64_t voxel = grid.voxelOf(p);
                t.voxel = voxel >= 0 ? uint32_t(voxel) : piece.voxel;
                valid[i] = 1;
            }
        }
        size_t d = done += range.size();
        if (progress) progress(double(d) / double(requests.size()));
        std::lock_guard<std::mutex> lock(statsMutex);
        stats.rays += counters;
        stats.nonFinitePaths += nonFinite;
        stats.noisyPoints += noisy;
    });

    samples.reserve(out.size());
    for (size_t i = 0; i < out.size(); ++i) {
        if (hidden[i]) continue;  // counted above
        if (!valid[i]) {
            ++stats.droppedSamples;
            continue;
        }
        ++stats.perVoxel[out[i].voxel];
        samples.push_back(out[i]);
    }
    return samples;
}

}  // namespace nrad
