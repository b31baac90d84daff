// Light selection for next event estimation: the paper's Sec. 4 experiment (issue 6).
//
// Renders the scene (default scenes/split-rooms) with uniform, power and learned light selection, keeping
// the image at 1, 2, 4, ..., --max-spp samples per pixel, and compares each with a converged reference
// (power selection, --ref-spp; cached in --out). Reports, per mode and sample count: RMSE, RMSE of the
// images clamped to [0, 1] in units of 1/255 (the paper's unit), the wall time (training included) and the
// efficiency 1 / (MSE x time); the ratios uniform / learned; and writes false-colour images of the light
// chosen at each pixel's first hit. All modes run through the same round-based renderer in one process.
//
// Usage: nee_bench [scene.gltf] [--width W] [--max-spp N] [--ref-spp N] [--max-depth D] [--mix M]
//                  [--network-vertices N] [--train-batches N] [--warmup STEPS] [--lr R] [--quantum Q] [--seed S] [--out DIR]
//
// Modes: uniform, power, learned (warm-up of --warmup training steps on camera paths, then the network frozen;
// the default), learned-online (the paper's variant: trained between rounds throughout, every sample kept),
// candidates-only (uniform over the groups that pass the geometric test; no network).
#include <algorithm>
#include <chrono>
#include <functional>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <string>
#include <vector>

#include "baker/render/accel.h"
#include "baker/render/image_io.h"
#include "baker/lights/light_sampler.h"
#include "baker/lights/light_selection.h"
#include "baker/render/online_render.h"
#include "baker/render/path_tracer.h"
#include "baker/scene/gltf_loader.h"
#include "baker/validate/metrics.h"
#include "fma_peak.h"

using namespace nrad;

namespace {

double rmse255(const Image& a, const Image& ref) {
    double s = 0.0;
    for (size_t i = 0; i < a.pixels.size(); ++i)
        for (int c = 0; c < 3; ++c) {
            double d = std::clamp(double(a.pixels[i][c]), 0.0, 1.0) - std::clamp(double(ref.pixels[i][c]), 0.0, 1.0);
            s += d * d;
        }
    return 255.0 * std::sqrt(s / double(3 * a.pixels.size()));
}

// Share of the squared error held by the worst 0.1% of pixels: near 1 means a few outliers decide the RMSE.
double worstShare(const Image& a, const Image& ref) {
    std::vector<double> e(a.pixels.size());
    double total = 0.0;
    for (size_t i = 0; i < a.pixels.size(); ++i) {
        glm::vec3 d = a.pixels[i] - ref.pixels[i];
        e[i] = double(glm::dot(d, d));
        total += e[i];
    }
    size_t k = std::max<size_t>(1, e.size() / 1000);
    std::partial_sort(e.begin(), e.begin() + k, e.end(), std::greater<double>());
    double worst = 0.0;
    for (size_t i = 0; i < k; ++i) worst += e[i];
    return total > 0.0 ? worst / total : 0.0;
}

struct Row {
    std::string mode;
    int spp;
    double rmse, rmse255, seconds, trainingSeconds, worst;
};

}  // namespace

int main(int argc, char** argv) {
    std::string scenePath = std::string(NRAD_SOURCE_DIR) + "/scenes/split-rooms/split-rooms.gltf";
    std::string outDir = "nee-bench";
    int width = 256, maxSpp = 32, refSpp = 4096, maxDepth = 0;
    const NeeSettings defaults;
    float mix = defaults.mix;
    int networkVertices = defaults.networkVertices, trainBatches = defaults.trainBatches;
    uint32_t warmup = defaults.warmupSteps;
    uint32_t seed = 0;
    float learningRate = defaults.learningRate;
    int quantum = defaults.quantum;
    for (int i = 1; i < argc; ++i) {
        auto next = [&]() { return i + 1 < argc ? argv[++i] : (std::fprintf(stderr, "missing value\n"), std::exit(2), nullptr); };
        if (!std::strcmp(argv[i], "--width")) width = std::atoi(next());
        else if (!std::strcmp(argv[i], "--max-spp")) maxSpp = std::atoi(next());
        else if (!std::strcmp(argv[i], "--ref-spp")) refSpp = std::atoi(next());
        else if (!std::strcmp(argv[i], "--max-depth")) maxDepth = std::atoi(next());
        else if (!std::strcmp(argv[i], "--mix")) mix = float(std::atof(next()));
        else if (!std::strcmp(argv[i], "--out")) outDir = next();
        else if (!std::strcmp(argv[i], "--network-vertices")) networkVertices = std::atoi(next());
        else if (!std::strcmp(argv[i], "--train-batches")) trainBatches = std::atoi(next());
        else if (!std::strcmp(argv[i], "--warmup")) warmup = uint32_t(std::strtoul(next(), nullptr, 10));
        else if (!std::strcmp(argv[i], "--lr")) learningRate = float(std::atof(next()));
        else if (!std::strcmp(argv[i], "--quantum")) quantum = std::atoi(next());
        else if (!std::strcmp(argv[i], "--seed")) seed = uint32_t(std::strtoul(next(), nullptr, 10));
        else if (argv[i][0] != '-') scenePath = argv[i];
        else {
            std::fprintf(stderr, "usage: nee_bench [scene.gltf] [--width W] [--max-spp N] [--ref-spp N] [--max-depth D] "
                                 "[--mix M] [--network-vertices N] [--train-batches N] [--warmup STEPS] [--lr R] [--quantum Q] [--seed S] [--out DIR]\n");
            return 2;
        }
    }
    Scene scene = loadGltf(scenePath);
    Camera camera = scene.cameras.empty() ? frameBounds(scene.bounds) : scene.cameras[0];
    Accel accel(scene);
    LightSampler lights(scene);
    std::filesystem::create_directories(outDir);
    RenderSettings settings;
    settings.width = settings.height = width;
    settings.maxDepth = maxDepth;
    settings.seed = seed;  // the image's samples and (below) the networks' initial weights
    std::printf("scene %s: %zu light groups, %dx%d, max depth %d\n", scenePath.c_str(), lights.groupCount(), width,
                width, maxDepth);

    // Reference (cached).
    std::string refPath = outDir + "/reference-" + std::to_string(width) + "-" + std::to_string(refSpp) + "-d" +
                          std::to_string(maxDepth) + ".exr";
    Image reference;
    if (std::filesystem::exists(refPath)) {
        reference = readExr(refPath);
    } else {
        PathTracer tracer(scene, accel, lights);
        RenderSettings r = settings;
        r.spp = refSpp;
        r.seed = 0x5eed;
        RenderStats st;
        reference = tracer.render(camera, r, &st);
        writeExr(refPath, reference);
        std::printf("reference: %d spp in %.1f s\n", refSpp, st.seconds);
    }

    // Cost of one network evaluation (forward pass, one thread).
    {
        NeeSettings ns;
        ns.mode = NeeMode::Learned;
        LightSelector selector(lights, scene.bounds, ns);
        const int n = 200000;
        float probs[LightSampler::kMaxLightGroups];
        uint64_t all = (lights.groupCount() >= 64) ? ~uint64_t(0) : ((uint64_t(1) << lights.groupCount()) - 1);
        double sink = 0.0;
        auto t0 = std::chrono::steady_clock::now();
        for (int i = 0; i < n; ++i) {
            float t = float(i) / float(n);
            selector.networkDistribution(scene.bounds.lower + t * scene.bounds.extent(), glm::vec3(0, 1, 0),
                                         glm::normalize(glm::vec3(t, 1.0f, 0.5f)), all, probs);
            sink += probs[0];
        }
        double s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
        std::printf("network: %.0f ns per evaluation incl. input and softmax (one thread; checksum %.3f)\n",
                    1e9 * s / n, sink);
        // The forward pass alone, against this core's FMA peak measured now: the layers execute
        // 9 x 64 + 64 x 64 + 64 x padded-outputs multiply-adds.
        const NeeNetwork& net = selector.network();
        std::vector<float> X(size_t(n) * kNeeInputs);
        for (size_t i = 0; i < X.size(); ++i) X[i] = float((i * 2654435761u) % 1000u) / 500.0f - 1.0f;
        NeeNetwork::Activations a;
        t0 = std::chrono::steady_clock::now();
        for (int i = 0; i < n; ++i) {
            net.forward(&X[size_t(i) * kNeeInputs], a);
            sink += a.logits[0];
        }
        s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
        const int padded = net.outputs() <= 16 ? 16 : net.outputs() <= 32 ? 32 : 64;
        const double fmas = double(kNeeInputs * kNeeHidden + kNeeHidden * kNeeHidden + kNeeHidden * padded);
        std::printf("network forward pass: %.0f ns (%.0f multiply-adds)", 1e9 * s / n, fmas);
#if defined(__x86_64__)
        if (int lanes = fma_peak::widestFmaWidth()) {
            double peak = fma_peak::fmaPeak(1, lanes);
            std::printf(" = %.0f%% of this core's FMA peak (%.1f G lane-FMA/s, %d-wide; checksum %.3f)", 100.0 * fmas * n / s / peak,
                        peak * 1e-9, lanes, sink);
        }
#endif
        std::printf("\n");
    }

    std::vector<int> snaps;
    for (int s = 1; s <= maxSpp; s *= 2) snaps.push_back(s);
    settings.spp = snaps.back();
    std::vector<Row> rows;
    struct ModeRun {
        const char* name;
        NeeMode mode;
        float mix;
        uint32_t warmup;
    };
    const ModeRun runs[] = {{"uniform", NeeMode::Uniform, mix, 0},
                            {"power", NeeMode::Power, mix, 0},
                            {"learned", NeeMode::Learned, mix, warmup},
                            {"learned-online", NeeMode::Learned, mix, 0},
                            {"candidates-only", NeeMode::Learned, 1.0f, 0}};  // learned with mix 1: no network
    for (const ModeRun& run : runs) {
        NeeSettings ns;
        ns.mode = run.mode;
        ns.mix = run.mix;
        ns.networkVertices = networkVertices;
        ns.trainBatches = trainBatches;
        ns.warmupSteps = run.warmup;
        ns.seed = seed;
        ns.learningRate = learningRate;
        ns.quantum = quantum;
        LightSelector selector(lights, scene.bounds, ns);
        if (run.mix >= 1.0f) selector.setTraining(false);
        PathTracer tracer(scene, accel, lights, &selector);
        OnlineRenderResult r = renderOnline(tracer, &selector, camera, settings, snaps);
        for (const OnlineSnapshot& s : r.snapshots) {
            ImageMetrics m = compareImages(s.image, reference);
            rows.push_back({run.name, s.spp, m.rmse, rmse255(s.image, reference), s.seconds, 0.0, worstShare(s.image, reference)});
        }
        rows.back().trainingSeconds = r.stats.trainingSeconds;
        Image chosen(width, width);
        for (size_t i = 0; i < chosen.pixels.size(); ++i) chosen.pixels[i] = lightGroupColor(r.firstLight[i]);
        writePng(outDir + "/chosen-light-" + run.name + ".png", chosen);
        writePng(outDir + "/" + std::string(run.name) + "-" + std::to_string(snaps.back()) + "spp.png", r.image);
        writePng(outDir + "/" + std::string(run.name) + "-" + std::to_string(snaps.back()) + "spp-error.png",
                 squaredDifferenceImage(r.image, reference, 1e4f));
        if (!r.snapshots.empty() && r.snapshots.size() > 2)
            writePng(outDir + "/" + std::string(run.name) + "-4spp.png", r.snapshots[2].image);
        std::printf("%-16s %d spp: %.2f s (warm-up %llu paths %.2f s; training %.2f s, %llu steps), %.2f Mrays/s\n",
                    run.name, snaps.back(), r.stats.render.seconds, (unsigned long long)r.stats.warmupPaths,
                    r.stats.warmupSeconds, r.stats.trainingSeconds, (unsigned long long)r.stats.trainingSteps,
                    r.stats.render.raysPerSecond() * 1e-6);
    }

    std::string csv = outDir + "/nee-bench.csv";
    FILE* f = std::fopen(csv.c_str(), "w");
    if (f) std::fprintf(f, "mode,spp,rmse,rmse_x255_clamped,seconds,efficiency\n");
    std::printf("\n%-16s %5s %12s %12s %9s %14s %12s\n", "mode", "spp", "RMSE", "RMSE(1/255)", "time s", "1/(MSE x s)",
                "worst 0.1%");
    for (const Row& r : rows) {
        double eff = 1.0 / (r.rmse * r.rmse * r.seconds);
        std::printf("%-16s %5d %12.5f %12.2f %9.3f %14.4g %11.1f%%\n", r.mode.c_str(), r.spp, r.rmse, r.rmse255, r.seconds,
                    eff, 100.0 * r.worst);
        if (f) std::fprintf(f, "%s,%d,%.6g,%.6g,%.6g,%.6g\n", r.mode.c_str(), r.spp, r.rmse, r.rmse255, r.seconds, eff);
    }
    if (f) std::fclose(f);
    auto find = [&](const char* mode, int spp) -> const Row* {
        for (const Row& r : rows)
            if (r.mode == mode && r.spp == spp) return &r;
        return nullptr;
    };
    for (const char* learned : {"learned", "learned-online"}) {
        std::printf("\nuniform / %s:\n%5s %12s %18s\n", learned, "spp", "RMSE ratio", "efficiency ratio");
        for (int s : snaps) {
            const Row *u = find("uniform", s), *l = find(learned, s);
            if (!u || !l) continue;
            std::printf("%5d %12.2f %18.2f\n", s, u->rmse / l->rmse,
                        (u->rmse * u->rmse * u->seconds) / (l->rmse * l->rmse * l->seconds));
        }
    }
    std::printf("\nwrote %s and images in %s\n", csv.c_str(), outDir.c_str());
    return 0;
}
