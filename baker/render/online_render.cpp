// Rendering in rounds with online training of the light-selection network.
#include "baker/render/online_render.h"

#include <algorithm>
#include <chrono>
#include <cmath>

#include <tbb/parallel_for.h>

#include "baker/nn/random.h"
#include "baker/nn/schedule.h"

namespace nrad {

namespace {

using Clock = std::chrono::steady_clock;
double since(Clock::time_point t) { return std::chrono::duration<double>(Clock::now() - t).count(); }

// Runs paths [begin, end) in mini-batches of 64 in parallel; per mini-batch records (if wanted) and counters
// are kept apart and merged in mini-batch order, so the result does not depend on the threads.
template <typename PathFn>
void runRound(uint64_t begin, uint64_t end, std::vector<NeeRecord>* records, RayCounters& counters, PathFn&& path) {
    const uint64_t batches = (end - begin + 63) / 64;
    std::vector<std::vector<NeeRecord>> batchRecords(records ? batches : 0);
    std::vector<RayCounters> batchCounters(batches);
    tbb::parallel_for(uint64_t(0), batches, [&](uint64_t b) {
        NeeTrace nee;
        nee.records = records ? &batchRecords[b] : nullptr;
        for (uint64_t k = begin + b * 64; k < std::min(end, begin + (b + 1) * 64); ++k) path(k, nee, batchCounters[b]);
    });
    if (records) {
        records->clear();
        for (uint64_t b = 0; b < batches; ++b) records->insert(records->end(), batchRecords[b].begin(), batchRecords[b].end());
    }
    for (uint64_t b = 0; b < batches; ++b) counters += batchCounters[b];
}

// Learning-rate schedule of a warm-up (training that ends with the network frozen), `done` of `total` (paths
// or steps) behind: linear decay from the full rate to zero, so the frozen weights are not one noisy step's
// (better than a constant rate: docs/design.md).
float warmupLearningRateScale(uint64_t done, uint64_t total) {
    return total > 0 ? linearDecay(1.0f, float(double(done) / double(total))) : 1.0f;
}

// Mini-batches of 64 paths in a warm-up round: enough for trainBatches x 64 useful records at the previous
// round's yield (records per path: about 1 for direct light with a trained network, several for long
// paths, fewer while untrained), 1 to 16. Deterministic: the yield is a count of the previous round.
uint64_t warmupBatches(int trainBatches, double yield) {
    double paths = double(trainBatches) * 64.0 / std::max(yield, 1.0 / 64.0);
    return uint64_t(std::clamp(std::ceil(paths / 64.0), 1.0, 16.0));
}

// Sampler seed of the warm-up paths (distinct from the image's streams).
constexpr uint32_t kWarmupSeed = 0x7761726du;  // "warm"

bool finite3(const glm::vec3& v) { return std::isfinite(v.x) && std::isfinite(v.y) && std::isfinite(v.z); }

}  // namespace

glm::vec3 lightGroupColor(int group) {
    if (group < 0) return glm::vec3(0.0f);
    // Evenly spaced hues (golden-angle steps), full saturation.
    float h = std::fmod(float(group) * 0.618034f, 1.0f) * 6.0f;
    float x = 1.0f - std::abs(std::fmod(h, 2.0f) - 1.0f);
    int sector = int(h);
    glm::vec3 c = sector == 0 ? glm::vec3(1, x, 0) : sector == 1 ? glm::vec3(x, 1, 0) : sector == 2 ? glm::vec3(0, 1, x)
                : sector == 3 ? glm::vec3(0, x, 1) : sector == 4 ? glm::vec3(x, 0, 1) : glm::vec3(1, 0, x);
    return c;
}

OnlineRenderResult renderOnline(const PathTracer& tracer, LightSelector* trainee, const Camera& camera,
                                const RenderSettings& settings, const std::vector<int>& snapshotSpp,
                                const std::function<void(double)>& progress) {
    auto start = Clock::now();
    OnlineRenderResult result;
    const int W = settings.width, H = settings.height;
    const uint64_t P = uint64_t(W) * uint64_t(H);
    const int spp = std::max(0, settings.spp);
    CameraRays rays(camera, W, H);
    std::vector<glm::dvec3> sum(P, glm::dvec3(0.0));
    result.firstLight.assign(P, -1);

    // A fixed shuffle of the pixels (Fisher-Yates), so each round's samples spread over the image.
    std::vector<uint32_t> order(P);
    for (uint64_t i = 0; i < P; ++i) order[i] = uint32_t(i);
    SplitMix64 rng(0x6f6e6c696e65ull ^ settings.seed);
    for (uint64_t i = P; i > 1; --i) std::swap(order[i - 1], order[rng.below(i)]);

    const bool learning = trainee && trainee->mode() == NeeMode::Learned && trainee->settings().train;
    const uint64_t roundSize = uint64_t(trainee ? trainee->settings().batchesPerRound : 16) * 64;
    std::vector<NeeRecord> records;
    RayCounters counters;
    // One camera path through pixel order[k % P] with its sampler (stream seed, sample index).
    auto cameraPath = [&](uint64_t k, uint32_t seed, uint32_t index, NeeTrace& nee, RayCounters& c) {
        uint32_t pixel = order[k % P];
        int x = int(pixel % uint32_t(W)), y = int(pixel / uint32_t(W));
        glm::vec3 o, d;
        Sampler sampler = cameraSample(rays, x, y, seed, index, o, d);
        nee.firstLight = -1;
        return tracer.radiance(o, d, sampler, settings.maxDepth, c, nullptr, &nee);
    };
    auto train = [&](float lrScale, int maxSteps) {
        auto t = Clock::now();
        trainee->train(records, lrScale, maxSteps);
        result.stats.trainingSeconds += since(t);
    };

    // Warm-up: camera paths with their own sampler streams, in training rounds; the image keeps nothing.
    if (learning && trainee->settings().warmupSteps > 0 && trainee->groupCount() > 1) {
        const NeeSettings& ns = trainee->settings();
        // Rounds until the steps are taken; it gives up after 8 rounds in a row record nothing (no light
        // reaches what the camera sees) or twice the rounds a normal warm-up needs.
        const uint64_t target = ns.warmupSteps, steps0 = trainee->trainingSteps() + trainee->rejectedSteps();
        const uint64_t maxRounds = 2 * ((target + uint64_t(ns.trainBatches) - 1) / uint64_t(ns.trainBatches));
        RayCounters warmupRays;
        uint64_t next = 0;  // warm-up path index: pixel order[k % P], sample k / P
        double yield = 1.0;  // useful records per path in the previous round
        int emptyRounds = 0;
        for (uint64_t round = 0, taken = 0; taken < target && round < maxRounds && emptyRounds < 8; ++round) {
            uint64_t paths = 64 * warmupBatches(ns.trainBatches, yield);
            runRound(next, next + paths, &records, warmupRays, [&](uint64_t k, NeeTrace& nee, RayCounters& c) {
                cameraPath(k, settings.seed ^ kWarmupSeed, uint32_t(k / P), nee, c);
            });
            next += paths;
            yield = double(records.size()) / double(paths);
            emptyRounds = records.empty() ? emptyRounds + 1 : 0;
            ++result.stats.rounds;
            result.stats.records += records.size();
            train(warmupLearningRateScale(taken, target), int(std::min<uint64_t>(target - taken, 1u << 30)));
            taken = trainee->trainingSteps() + trainee->rejectedSteps() - steps0;
        }
        trainee->setTraining(false);
        result.stats.warmupPaths = next;
        result.stats.warmupSeconds = since(start);
    }

    // The image: in training rounds while the network learns, else a whole pass at a time.
    const bool online = learning && trainee->settings().train;
    const uint64_t passRound = online ? roundSize : P;
    uint64_t nonFinite = 0;
    std::vector<uint8_t> bad(P, 0);
    for (int s = 0; s < spp; ++s) {
        for (uint64_t begin = 0; begin < P; begin += passRound) {
            uint64_t end = std::min(P, begin + passRound);
            runRound(begin, end, online ? &records : nullptr, counters, [&](uint64_t k, NeeTrace& nee, RayCounters& c) {
                uint32_t pixel = order[k];
                glm::vec3 L = cameraPath(k, settings.seed, uint32_t(s), nee, c);
                if (finite3(L))
                    sum[pixel] += glm::dvec3(L);
                else
                    bad[pixel] = 1;
                result.firstLight[pixel] = nee.firstLight;
            });
            if (online) {
                ++result.stats.rounds;
                result.stats.records += records.size();
                train(1.0f, 1 << 30);
            }
        }
        for (uint64_t i = 0; i < P; ++i) {
            nonFinite += bad[i];
            bad[i] = 0;
        }
        if (std::find(snapshotSpp.begin(), snapshotSpp.end(), s + 1) != snapshotSpp.end()) {
            OnlineSnapshot snap;
            snap.spp = s + 1;
            snap.seconds = since(start);
            snap.image = Image(W, H);
            for (uint64_t i = 0; i < P; ++i) snap.image.pixels[i] = glm::vec3(sum[i] / double(s + 1));
            result.snapshots.push_back(std::move(snap));
        }
        if (progress) progress(double(s + 1) / double(std::max(1, spp)));
    }
    result.image = Image(W, H);
    for (uint64_t i = 0; i < P; ++i) result.image.pixels[i] = glm::vec3(sum[i] / double(std::max(1, spp)));
    counters.nonFiniteSamples += nonFinite;
    result.stats.render.seconds = since(start);
    result.stats.render.samples = P * uint64_t(spp);
    result.stats.render.rays = counters;
    result.stats.trainingSteps = trainee ? trainee->trainingSteps() : 0;
    return result;
}

WarmupStats trainSelectorOnPaths(const PathTracer& tracer, LightSelector& trainee, uint64_t paths, int maxDepth,
                                 const std::function<SurfaceInteraction(uint64_t, uint32_t&, uint32_t&)>& start) {
    auto t0 = Clock::now();
    WarmupStats stats;
    const uint64_t roundSize = uint64_t(trainee.settings().batchesPerRound) * 64;
    std::vector<NeeRecord> records;
    uint64_t steps0 = trainee.trainingSteps();
    for (uint64_t begin = 0; begin < paths; begin += roundSize) {
        uint64_t end = std::min(paths, begin + roundSize);
        runRound(begin, end, &records, stats.rays, [&](uint64_t k, NeeTrace& nee, RayCounters& c) {
            uint32_t stream = 0, index = 0;
            SurfaceInteraction si = start(k, stream, index);
            Sampler sampler(stream, index);
            tracer.outgoingRadiance(si, sampler, maxDepth, c, &nee);
        });
        stats.records += records.size();
        trainee.train(records, warmupLearningRateScale(begin, paths));
    }
    stats.paths = paths;
    stats.trainingSteps = trainee.trainingSteps() - steps0;
    stats.seconds = since(t0);
    return stats;
}

}  // namespace nrad
