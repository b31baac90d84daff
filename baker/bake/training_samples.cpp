// Training-sample generation: area-uniform points on clipped surface pieces, path-traced radiance.
#include "baker/bake/training_samples.h"

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <mutex>

#include <tbb/parallel_for.h>
#include <tbb/parallel_sort.h>

#include <nrad/check.h>

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

// Where the points' paths start: the scene, the surface pieces the points are drawn on, and the tracer that
// says whether a viewer sees them.
struct PointStarts {
    const Scene& scene;
    const PathTracer& tracer;
    const SurfacePieces& pieces;
    const SampleSettings& settings;

    // The point, its outgoing direction and the interaction the paths start from.
    SurfaceInteraction startOf(const PointRequest& r, glm::vec3& p, glm::vec3& wo) const {
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
    }

    // Points no viewer sees from their direction are dropped before anything is traced from them, and the
    // floor counts only the points that remain.
    bool hiddenFrom(const PointRequest& r) const {
        if (!settings.dropHidden) return false;
        glm::vec3 p, wo;
        return !tracer.viewable(startOf(r, p, wo));
    }
};

// Pass 1: points uniform by area over the whole surface (decided up front, cheap, so that the expensive path
// tracing runs as one parallel loop).
std::vector<PointRequest> areaRequests(const SurfacePieces& pieces, const SampleSettings& settings) {
    std::vector<double> cdf;
    cdf.reserve(pieces.pieces().size());
    double acc = 0.0;
    for (const SurfacePiece& p : pieces.pieces()) cdf.push_back(acc += p.area);
    uint32_t pointStream = hashCombine(settings.seed, kPointStream);
    std::vector<PointRequest> requests(settings.points);
    tbb::parallel_for(tbb::blocked_range<uint32_t>(0, settings.points, 1024), [&](const tbb::blocked_range<uint32_t>& range) {
        for (uint32_t k = range.begin(); k != range.end(); ++k) {
            const uint32_t i = settings.firstPoint + k;
            Sampler s(pointStream, i);
            float uPiece = s.get1D();
            requests[k] = {uint32_t(pickByCdf(cdf, uPiece)), s.get2D(), s.get2D(), hashCombine(hashCombine(settings.seed, kPathStream), i)};
        }
    });
    return requests;
}

// Marks the requests no viewer sees; returns the points a viewer sees per voxel.
std::vector<uint32_t> countSeen(const PointStarts& starts, const VoxelGrid& grid, const std::vector<PointRequest>& requests,
                                std::vector<uint8_t>& hidden, SampleStats& stats) {
    std::vector<uint32_t> count(grid.voxelCount(), 0);
    hidden.assign(requests.size(), 0);
    tbb::parallel_for(tbb::blocked_range<size_t>(0, requests.size(), 256), [&](const tbb::blocked_range<size_t>& range) {
        for (size_t i = range.begin(); i != range.end(); ++i) hidden[i] = starts.hiddenFrom(requests[i]);
    });
    for (size_t i = 0; i < requests.size(); ++i) {
        if (hidden[i]) {
            ++stats.hiddenSamples;
            continue;
        }
        ++count[starts.pieces.pieces()[requests[i].piece].voxel];
    }
    return count;
}

// Pass 2: the floor, voxel by voxel (in parallel, each voxel from its own stream): candidates from the voxel's
// own surface until it has the floor's number of points a viewer sees, or 16 times the floor was tried (a
// voxel whose surface is all hidden keeps what it has). Appended to `requests` in voxel order.
void addFloor(const PointStarts& starts, const VoxelGrid& grid, const std::vector<uint32_t>& count, std::vector<PointRequest>& requests,
              SampleStats& stats) {
    const SampleSettings& settings = starts.settings;
    const SurfacePieces& pieces = starts.pieces;
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
            if (!starts.hiddenFrom(r)) floorOf[v].push_back(r);
        }
    });
    for (const std::vector<PointRequest>& f : floorOf) {
        requests.insert(requests.end(), f.begin(), f.end());
        stats.floorPoints += f.size();
    }
}

// Learned light selection: train the network on paths from these points first, then keep it fixed.
void warmUpSelector(const PointStarts& starts, const std::vector<PointRequest>& requests, LightSelector& trainee, SampleStats& stats) {
    const uint64_t n = requests.size();
    WarmupStats w = trainSelectorOnPaths(starts.tracer, trainee, starts.settings.neeWarmupPaths, starts.settings.maxDepth,
                                         [&](uint64_t k, uint32_t& stream, uint32_t& index) {
                                             const PointRequest& r = requests[size_t(k % n)];
                                             stream = hashCombine(r.pathStream, kWarmupStream);
                                             index = uint32_t(k / n);
                                             glm::vec3 p, wo;
                                             return starts.startOf(r, p, wo);
                                         });
    trainee.setTraining(false);
    stats.neeWarmupPaths = w.paths;
    stats.neeTrainingSteps = w.trainingSteps;
    stats.neeWarmupSeconds = w.seconds;
    stats.rays += w.rays;
}

// One range of points traced together: the points kept, where their paths start, and every path's estimate
// (settings.paths per point, then the noisy points' extra paths, extraOf[k] of them for point k).
struct RangeBatch {
    std::vector<size_t> points;
    std::vector<SurfaceInteraction> starts;
    std::vector<glm::vec3> pointWo, pointP;
    std::vector<glm::vec3> estimates;
    std::vector<uint32_t> extraOf;
    RayCounters counters;
    uint64_t nonFinite = 0, noisy = 0, extraPaths = 0;
};

// The points at positions `range` of the tracing order (spatialOrder), but those a viewer does not see and those
// in an alpha cutout's hole (no surface: dropped, counted in droppedSamples).
void startRange(const PointStarts& ps, const std::vector<PointRequest>& requests, const std::vector<uint8_t>& hidden,
                const std::vector<uint32_t>& order, const tbb::blocked_range<size_t>& range, RangeBatch& batch) {
    for (size_t at = range.begin(); at != range.end(); ++at) {
        const size_t i = order[at];
        const PointRequest& r = requests[i];
        const SurfacePiece& piece = ps.pieces.pieces()[r.piece];
        glm::vec3 p, wo;
        SurfaceInteraction si = ps.startOf(r, p, wo);
        if (si.material && si.material->alphaMode == Material::AlphaMode::Mask) {
            float b1, b2;
            ps.pieces.samplePiece(piece, r.uPoint, b1, b2);
            if (surfaceOpacity(ps.scene, piece.triangle, b1, b2) <= 0.0f) continue;
        }
        if (hidden[i]) continue;
        batch.points.push_back(i);
        batch.starts.push_back(si);
        batch.pointP.push_back(p);
        batch.pointWo.push_back(wo);
    }
}

}  // namespace

uint32_t noisyExtraPaths(double mean, double variance, uint32_t n, const SampleSettings& settings) {
    if (settings.extraPathsFactor <= 1 || n < 2 || !(mean > 0.0)) return 0;
    // The mean of m paths has the relative variance r^2 n / m: m = n (r / b)^2 brings it to the bound b. Counted on
    // from the point's `paths`.
    const double relativeVariance = variance / (double(n) * mean * mean), bound = double(settings.noisyRelativeError);
    if (!(relativeVariance > bound * bound)) return 0;
    const double wanted = std::ceil(double(settings.paths) * (relativeVariance / (bound * bound) - 1.0));
    return uint32_t(std::min(double(settings.extraPathsFactor - 1) * double(settings.paths), wanted));  // (no u32 product to wrap)
}

uint32_t noisyExtraPaths(const glm::vec3* estimates, uint32_t count, const SampleSettings& settings) {
    double s1 = 0.0, s2 = 0.0;
    uint32_t n = 0;
    for (uint32_t j = 0; j < count; ++j) {
        const glm::vec3& L = estimates[j];
        if (!(std::isfinite(L.x) && std::isfinite(L.y) && std::isfinite(L.z))) continue;
        const double l = 0.2126 * L.x + 0.7152 * L.y + 0.0722 * L.z;
        s1 += l;
        s2 += l * l;
        ++n;
    }
    if (n < 2 || !(s1 > 0.0)) return 0;
    const double mean = s1 / n, var = std::max(0.0, s2 / n - mean * mean) * n / (n - 1);
    return noisyExtraPaths(mean, var, n, settings);
}

namespace {

// All the range's paths traced together (PathTracer::estimate, in batches). Noisy targets: points whose
// mean's relative standard error is above the bound get the paths that bring it there (noisyExtraPaths),
// traced together as well (paths numbered on from settings.paths).
void traceRange(const PointStarts& ps, const std::vector<PointRequest>& requests, const TargetEstimator& estimator, RangeBatch& batch) {
    const SampleSettings& settings = ps.settings;
    const std::vector<size_t>& points = batch.points;
    std::vector<PathStart> paths;
    paths.reserve(points.size() * settings.paths);
    for (size_t k = 0; k < points.size(); ++k)
        for (uint32_t j = 0; j < settings.paths; ++j) paths.push_back({&batch.starts[k], requests[points[k]].pathStream, j});
    batch.estimates.resize(paths.size());
    ps.tracer.estimate(paths.data(), paths.size(), settings.maxDepth, estimator.tail, estimator.bounces, batch.counters,
                       batch.estimates.data());
    batch.extraOf.assign(points.size(), 0);
    const bool adaptive = !estimator.tail && settings.extraPathsFactor > 1 && settings.paths > 1;
    if (!adaptive) return;
    std::vector<PathStart> more;
    for (size_t k = 0; k < points.size(); ++k) {
        const uint32_t extra = noisyExtraPaths(&batch.estimates[k * settings.paths], settings.paths, settings);
        if (extra == 0) continue;
        batch.extraOf[k] = extra;
        batch.extraPaths += extra;
        for (uint32_t j = 0; j < extra; ++j) more.push_back({&batch.starts[k], requests[points[k]].pathStream, settings.paths + j});
    }
    if (!more.empty()) {
        const size_t at = batch.estimates.size();
        batch.estimates.resize(at + more.size());
        ps.tracer.estimate(more.data(), more.size(), settings.maxDepth, estimator.tail, estimator.bounces, batch.counters,
                           batch.estimates.data() + at);
    }
}

// Each point's sample from the mean of its finite estimates (valid[i] set where there is one).
void storeTargets(const PointStarts& ps, const VoxelGrid& grid, const std::vector<PointRequest>& requests,
                  const TargetEstimator& estimator, RangeBatch& batch, std::vector<TrainingSample>& out, std::vector<uint8_t>& valid) {
    const uint32_t pathsPerPoint = ps.settings.paths;
    size_t extraAt = batch.points.size() * pathsPerPoint;
    for (size_t k = 0; k < batch.points.size(); ++k) {
        const size_t i = batch.points[k];
        const SurfacePiece& piece = ps.pieces.pieces()[requests[i].piece];
        const SurfaceInteraction& si = batch.starts[k];
        const glm::vec3 &p = batch.pointP[k], &wo = batch.pointWo[k];
        glm::dvec3 sum(0.0);
        uint32_t finite = 0;
        auto add = [&](const glm::vec3& L) {
            if (std::isfinite(L.x) && std::isfinite(L.y) && std::isfinite(L.z)) {
                sum += glm::dvec3(L);
                ++finite;
            } else {
                ++batch.nonFinite;
            }
        };
        for (uint32_t j = 0; j < pathsPerPoint; ++j) add(batch.estimates[k * pathsPerPoint + j]);
        for (uint32_t j = 0; j < batch.extraOf[k]; ++j) add(batch.estimates[extraAt + j]);
        extraAt += batch.extraOf[k];
        if (batch.extraOf[k] > 0) ++batch.noisy;
        if (finite == 0) continue;
        TrainingSample& t = out[i];
        t.position = p;
        t.normal = si.ns;
        t.wo = wo;
        // The target is the radiance the point scatters, L - Le: its own emission is exact and is added back
        // by whoever shades (nrad/eval.h, shade()), so no network has to draw an emitter's edge. Rounding can
        // leave -1 ulp: clamped.
        const glm::vec3 own = estimator.tail ? glm::vec3(0.0f) : si.emission;  // the tail's estimates have none
        t.radiance = glm::max(glm::vec3(sum / double(finite)) - own, glm::vec3(0.0f));
        float refl[3];
        eval::reflectance(shadingSurface(si), glm::dot(si.ns, wo), refl);
        t.reflectance = glm::vec3(refl[0], refl[1], refl[2]);
        // The voxel the runtime will look up for p (the format's rule): a point on a border plane belongs to
        // the voxel above it, whichever piece it was sampled from.
        int64_t voxel = grid.voxelOf(p);
        t.voxel = voxel >= 0 ? uint32_t(voxel) : piece.voxel;
        valid[i] = 1;
    }
}

// The order in which the points are traced: along a Morton curve through the scene's box (by each point's
// position, 21 bits an axis), so that a chunk's paths start near each other and meet the same parts of the scene
// (the acceleration structure's nodes and the triangles' data stay in the caches): zdm2's sampling 10-17% faster
// (docs/performance.md). Each point's samples depend on its own request alone, so the order changes no bit; ties
// keep the list order.
std::vector<uint32_t> spatialOrder(const PointStarts& ps, const std::vector<PointRequest>& requests) {
    const Bounds3& b = ps.scene.bounds;
    const glm::vec3 extent = glm::max(b.upper - b.lower, glm::vec3(1e-30f));
    std::vector<std::pair<uint64_t, uint32_t>> keys(requests.size());
    auto spread = [](uint64_t x) {  // 21 bits to every third bit
        x &= 0x1fffff;
        x = (x | x << 32) & 0x1f00000000ffffull;
        x = (x | x << 16) & 0x1f0000ff0000ffull;
        x = (x | x << 8) & 0x100f00f00f00f00full;
        x = (x | x << 4) & 0x10c30c30c30c30c3ull;
        x = (x | x << 2) & 0x1249249249249249ull;
        return x;
    };
    tbb::parallel_for(tbb::blocked_range<size_t>(0, requests.size(), 4096), [&](const tbb::blocked_range<size_t>& range) {
        for (size_t i = range.begin(); i != range.end(); ++i) {
            const PointRequest& r = requests[i];
            float b1, b2;
            const glm::vec3 p = ps.pieces.samplePiece(ps.pieces.pieces()[r.piece], r.uPoint, b1, b2);
            uint64_t key = 0;
            for (int k = 0; k < 3; ++k) {
                const float t = std::clamp((p[k] - b.lower[k]) / extent[k], 0.0f, 1.0f);
                key |= spread(uint64_t(std::min(t * 2097152.0f, 2097151.0f))) << k;
            }
            keys[i] = {key, uint32_t(i)};
        }
    });
    tbb::parallel_sort(keys.begin(), keys.end());  // (the pairs are distinct: one order)
    std::vector<uint32_t> order(requests.size());
    for (size_t i = 0; i < keys.size(); ++i) order[i] = keys[i].second;
    return order;
}

// Whether a sample received from elsewhere can be one this bake traced: its voxel in the grid, every value finite.
bool plausible(const TrainingSample& t, uint64_t voxels) {
    const glm::vec3* v[5] = {&t.position, &t.normal, &t.wo, &t.radiance, &t.reflectance};
    for (const glm::vec3* x : v)
        if (!std::isfinite(x->x) || !std::isfinite(x->y) || !std::isfinite(x->z)) return false;
    return t.voxel < voxels;
}

// Every process's traced blocks (of positions in the tracing order `order`) into `out` and `valid`, and the counts
// of its paths summed into `stats` (the points' counts, decided before tracing, are every process's own). In rounds
// of at most 64 blocks from each process, so that what is in flight stays small beside `out` (all of it at once
// doubled a process's peak memory).
void gatherShares(const BakeGroup& group, const BlockShares& shares, const std::vector<uint32_t>& order, std::vector<TrainingSample>& out,
                  std::vector<uint8_t>& valid, SampleStats& stats, uint64_t voxels) {
    {
        ByteWriter w;
        w.put(stats.rays);
        w.put(stats.nonFinitePaths);
        w.put(stats.noisyPoints);
        w.put(stats.extraPaths);
        const std::vector<std::vector<uint8_t>> all = group.allGather(w.bytes);
        if (!all.empty()) {  // (empty: a shard recording its share, bake_shard.h, keeps its own counts)
            stats.rays = RayCounters{};
            stats.nonFinitePaths = stats.noisyPoints = stats.extraPaths = 0;
        }
        for (const std::vector<uint8_t>& bytes : all) {
            ByteReader in(bytes);
            stats.rays += in.get<RayCounters>();
            stats.nonFinitePaths += in.get<uint64_t>();
            stats.noisyPoints += in.get<uint64_t>();
            stats.extraPaths += in.get<uint64_t>();
        }
    }
    constexpr size_t kRound = 64;
    for (size_t j0 = 0; j0 < shares.blocksOf(0); j0 += kRound) {  // process 0 has the most blocks
        ByteWriter w;
        for (size_t j = j0; j < std::min(j0 + kRound, shares.blocksOf(group.rank())); ++j) {
            const Share b = shares.blockOf(group.rank(), j);
            for (size_t at = b.first; at < b.last; ++at) {
                const size_t i = order[at];
                w.put(valid[i]);
                if (valid[i]) w.put(out[i]);
            }
        }
        const std::vector<std::vector<uint8_t>> all = group.allGather(w.bytes);
        if (all.empty()) continue;  // recorded (a shard)
        for (int r = 0; r < group.size(); ++r) {
            ByteReader in(all[size_t(r)]);
            for (size_t j = j0; j < std::min(j0 + kRound, shares.blocksOf(r)); ++j) {
                const Share b = shares.blockOf(r, j);
                for (size_t at = b.first; at < b.last; ++at) {
                    const size_t i = order[at];
                    valid[i] = in.get<uint8_t>();
                    if (valid[i]) out[i] = in.get<TrainingSample>();
                    if (valid[i] && !plausible(out[i], voxels))  // (read from a file where a shard replays them)
                        throw std::runtime_error("bake group: a traced sample out of range or not finite");
                }
            }
            if (!in.done()) throw std::runtime_error("bake group: a process traced other points");
        }
    }
}
}  // namespace

std::vector<TrainingSample> generateTrainingSamples(const Scene& scene, const PathTracer& tracer, const VoxelGrid& grid,
                                                    const SurfacePieces& pieces, const SampleSettings& settings,
                                                    SampleStats& stats, const std::function<void(double)>& progress,
                                                    LightSelector* trainee, const TargetEstimator& estimator,
                                                    const BakeGroup* group) {
    NRAD_CHECK(settings.points > 0 && settings.paths > 0);  // 0 means automatic: resolvedBakeSettings first
    stats = SampleStats{};
    stats.perVoxel.assign(grid.voxelCount(), 0);
    if (pieces.pieces().empty()) return {};

    // The points: pass 1 by area, then the floor per voxel, all decided before any path is traced.
    const auto planStart = std::chrono::steady_clock::now();
    const PointStarts ps{scene, tracer, pieces, settings};
    std::vector<PointRequest> requests = areaRequests(pieces, settings);
    std::vector<uint8_t> hidden;
    const std::vector<uint32_t> count = countSeen(ps, grid, requests, hidden, stats);
    stats.points = settings.points;
    addFloor(ps, grid, count, requests, stats);
    hidden.resize(requests.size(), 0);
    stats.planSeconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - planStart).count();
    const bool traces = !group || group->traces();  // false: the paths come from elsewhere (a shard's first stage)
    // (Warmed up even then: the volume's paths, traced later by every process, use the selector too.)
    if (trainee && trainee->mode() == NeeMode::Learned && settings.neeWarmupPaths > 0 && !requests.empty())
        warmUpSelector(ps, requests, *trainee, stats);

    // The paths, range by range in parallel: this process's share of the points (all of them without a group), in
    // the tracing order.
    NRAD_CHECK(requests.size() < size_t(UINT32_MAX));
    const std::vector<uint32_t> order = spatialOrder(ps, requests);
    std::vector<TrainingSample> out(requests.size());
    std::vector<uint8_t> valid(requests.size(), 0);
    const int rank = group ? group->rank() : 0;
    std::atomic<size_t> done{0};
    std::mutex statsMutex;
    // Chunks of enough points for a few hundred paths (the tracer's batches), traced one after another within blocks
    // of eight, so that a chunk's buffers stay small (a scheduler's range was once a sixteenth of the points: zdm2's
    // at once took 190 MB); the samples depend on neither. This process traces its blocks of the order (every block
    // without a group), spread over it.
    const size_t chunk = std::max<size_t>(8, size_t(kBatchSize) / std::max<uint32_t>(1, settings.paths));
    const BlockShares shares{requests.size(), 8 * chunk, group ? group->size() : 1};
    const size_t mine = traces ? shares.blocksOf(rank) : 0;
    size_t myPoints = 0;
    for (size_t j = 0; j < mine; ++j) myPoints += shares.blockOf(rank, j).last - shares.blockOf(rank, j).first;
    tbb::parallel_for(tbb::blocked_range<size_t>(0, mine, 1), [&](const tbb::blocked_range<size_t>& blocks) {
        RangeBatch total;
        for (size_t j = blocks.begin(); j != blocks.end(); ++j) {
            const Share range = shares.blockOf(rank, j);
            for (size_t first = range.first; first < range.last; first += chunk) {
                RangeBatch batch;
                const tbb::blocked_range<size_t> part(first, std::min(range.last, first + chunk));
                startRange(ps, requests, hidden, order, part, batch);
                traceRange(ps, requests, estimator, batch);
                storeTargets(ps, grid, requests, estimator, batch, out, valid);
                total.counters += batch.counters;
                total.nonFinite += batch.nonFinite;
                total.noisy += batch.noisy;
                total.extraPaths += batch.extraPaths;
                const size_t d = done += part.size();
                if (progress) progress(double(d) / double(std::max<size_t>(1, myPoints)));
            }
        }
        std::lock_guard<std::mutex> lock(statsMutex);
        stats.rays += total.counters;
        stats.nonFinitePaths += total.nonFinite;
        stats.noisyPoints += total.noisy;
        stats.extraPaths += total.extraPaths;
    });

    if (group && group->exchanges()) gatherShares(*group, shares, order, out, valid, stats, grid.voxelCount());

    // The kept samples moved to the front of `out` in order, which then is the result (a copy, or shrinking it, would
    // hold both at once: 500 MB at the peak of a bake of 3.9 M samples).
    size_t kept = 0;
    for (size_t i = 0; i < out.size(); ++i) {
        if (hidden[i]) continue;  // counted above
        if (!valid[i]) {
            ++stats.droppedSamples;
            continue;
        }
        ++stats.perVoxel[out[i].voxel];
        out[kept++] = out[i];
    }
    out.resize(kept);
    return out;
}

}  // namespace nrad
