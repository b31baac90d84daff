// Path tracer throughput against raw Embree, measured in one run on the same rays.
//
// 1. Renders the scene once while recording every ray the path tracer issues (camera, extension and
//    shadow rays, in issue order): the tracer's own ray distribution.
// 2. Replays exactly those rays through plain rtcIntersect1 / rtcOccluded1 (no shading, no sampling):
//    the raw Embree rays/s.
// 3. Renders the same image with the path tracer and counts its rays/s.
// 4. For reference, the same rays through Embree's streams as the batched tracer issues them.
// Prints the rates and the tracer's ratio to each, for one thread and for all threads; best of several repetitions.
//
// Usage: path_tracer_bench [scene.gltf] [--width W] [--spp N] [--max-depth D] [--repeat R] [--batch B] [--tile T]
//                          [--tracer-only]
// (--tracer-only: render R times on one thread and print the tracer's rate alone, for a profiler.)
// (--batch 1: the one-path tracer instead of the batched one)
#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <string>
#include <thread>

#include <tbb/parallel_for.h>

#include "baker/render/accel.h"
#include "baker/lights/light_sampler.h"
#include "baker/render/path_tracer.h"
#include "baker/scene/gltf_loader.h"
#include "baker/util/threads.h"

using namespace nrad;

namespace {

double seconds(std::chrono::steady_clock::time_point a, std::chrono::steady_clock::time_point b) {
    return std::chrono::duration<double>(b - a).count();
}

double rawRaysPerSecond(const Accel& accel, const std::vector<RecordedRay>& rays, int repeat) {
    double best = 0.0;
    for (int r = 0; r < repeat; ++r) {
        std::atomic<size_t> hits{0};
        auto t0 = std::chrono::steady_clock::now();
        tbb::parallel_for(tbb::blocked_range<size_t>(0, rays.size(), 4096), [&](const tbb::blocked_range<size_t>& range) {
            hits += accel.traceRaw(rays.data() + range.begin(), range.size());
        });
        auto t1 = std::chrono::steady_clock::now();
        best = std::max(best, double(rays.size()) / seconds(t0, t1));
        if (hits.load() == 0) std::fprintf(stderr, "warning: no ray hit anything\n");
    }
    return best;
}

// The same rays through Embree's streams as the batched tracer issues them (Accel's batch queries, 256 at a
// time, closest-hit and shadow rays apart, each in recorded order): what Embree gives these rays at best.
double streamRaysPerSecond(const Accel& accel, const std::vector<RecordedRay>& rays, int repeat) {
    std::vector<RayQuery> hitRays, shadowRays;
    for (const RecordedRay& r : rays) (r.shadow ? shadowRays : hitRays).push_back({r.origin, r.direction, r.tnear, r.tfar});
    constexpr size_t kBatch = 256;
    double best = 0.0;
    for (int r = 0; r < repeat; ++r) {
        std::atomic<size_t> hits{0};
        auto t0 = std::chrono::steady_clock::now();
        // query(first ray, count) traces one batch and returns how many hit.
        auto inBatches = [&](const std::vector<RayQuery>& queries, const auto& query) {
            tbb::parallel_for(tbb::blocked_range<size_t>(0, (queries.size() + kBatch - 1) / kBatch), [&](const tbb::blocked_range<size_t>& range) {
                size_t n = 0;
                for (size_t b = range.begin(); b != range.end(); ++b)
                    n += query(queries.data() + b * kBatch, std::min(kBatch, queries.size() - b * kBatch));
                hits += n;
            });
        };
        inBatches(hitRays, [&](const RayQuery* q, size_t m) {
            Hit out[kBatch];
            accel.intersect(q, m, out);
            return size_t(std::count_if(out, out + m, [](const Hit& h) { return h.valid(); }));
        });
        inBatches(shadowRays, [&](const RayQuery* q, size_t m) {
            uint8_t out[kBatch];
            accel.occluded(q, m, out);
            return size_t(std::count(out, out + m, uint8_t(1)));
        });
        auto t1 = std::chrono::steady_clock::now();
        best = std::max(best, double(rays.size()) / seconds(t0, t1));
        if (hits.load() == 0) std::fprintf(stderr, "warning: no ray hit anything\n");
    }
    return best;
}

double tracerRaysPerSecond(const PathTracer& tracer, const Camera& camera, const RenderSettings& s, int repeat,
                           uint64_t* rayCount) {
    double best = 0.0;
    for (int r = 0; r < repeat; ++r) {
        RenderStats stats;
        tracer.render(camera, s, &stats);
        best = std::max(best, stats.raysPerSecond());
        *rayCount = stats.rays.total();
    }
    return best;
}

}  // namespace

int main(int argc, char** argv) {
    std::string scenePath = std::string(NRAD_SOURCE_DIR) + "/scenes/cornell-box/cornell-box.gltf";
    RenderSettings s;
    s.width = s.height = 128;
    s.spp = 16;
    int repeat = 3;
    bool tracerOnly = false;
    for (int i = 1; i < argc; ++i) {
        std::string a = argv[i];
        auto next = [&]() { return i + 1 < argc ? std::atoi(argv[++i]) : 0; };
        if (a == "--width") s.width = s.height = next();
        else if (a == "--spp") s.spp = next();
        else if (a == "--max-depth") s.maxDepth = next();
        else if (a == "--repeat") repeat = std::max(1, next());
        else if (a == "--batch") s.batchSize = std::max(1, next());
        else if (a == "--tile") s.tileSize = std::max(1, next());
        else if (a == "--tracer-only") tracerOnly = true;
        else scenePath = a;
    }
    Scene scene = loadGltf(scenePath);
    Accel accel(scene);
    LightSampler lights(scene);
    PathTracer tracer(scene, accel, lights);
    Camera camera = scene.cameras.empty() ? frameBounds(scene.bounds) : scene.cameras[0];

    if (tracerOnly) {
        ThreadScope scope(1);
        uint64_t tracerRays = 0;
        std::printf("tracer Mrays/s %.2f\n", tracerRaysPerSecond(tracer, camera, s, repeat, &tracerRays) * 1e-6);
        return 0;
    }
    std::vector<RecordedRay> rays = tracer.recordRays(camera, s);
    size_t shadow = size_t(std::count_if(rays.begin(), rays.end(), [](const RecordedRay& r) { return r.shadow; }));
    std::printf("scene %s, %dx%d, %d spp, max depth %d, batches of %d paths: %zu rays recorded (%zu closest-hit, %zu shadow)\n",
                scenePath.c_str(), s.width, s.height, s.spp, s.maxDepth, s.batchSize, rays.size(), rays.size() - shadow, shadow);
    std::printf("%-8s %16s %16s %8s %20s %8s\n", "threads", "Embree Mrays/s", "tracer Mrays/s", "ratio",
                "Embree streams Mr/s", "ratio");
    int hw = int(std::max(1u, std::thread::hardware_concurrency()));
    for (int threads : {1, hw}) {
        ThreadScope scope(threads);
        double raw = rawRaysPerSecond(accel, rays, repeat);
        double streams = streamRaysPerSecond(accel, rays, repeat);
        uint64_t tracerRays = 0;
        double traced = tracerRaysPerSecond(tracer, camera, s, repeat, &tracerRays);
        if (tracerRays != rays.size())
            std::fprintf(stderr, "warning: the render issued %llu rays, the recording %zu\n", (unsigned long long)tracerRays,
                         rays.size());
        std::printf("%-8d %16.2f %16.2f %7.1f%% %20.2f %7.1f%%\n", threads, raw * 1e-6, traced * 1e-6, 100.0 * traced / raw,
                    streams * 1e-6, 100.0 * traced / streams);
        if (hw == 1) break;
    }
    return 0;
}
