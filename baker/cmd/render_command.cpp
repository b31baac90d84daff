// `nrad render`: path-traced reference image of a glTF scene.
#include <chrono>
#include <cstdio>
#include <filesystem>
#include <map>
#include <memory>
#include <string>
#include <vector>

#include "baker/cmd/commands.h"
#include "baker/render/accel.h"
#include "baker/render/image_io.h"
#include "baker/lights/light_sampler.h"
#include "baker/render/neural_render.h"
#include "baker/render/online_render.h"
#include "baker/render/path_tracer.h"
#include "baker/util/progress.h"
#include "baker/util/threads.h"

#include <nrad/nrad.hpp>

namespace nrad {

namespace {

// Bytes a render holds per pixel at its peak (the float image, its 8-bit copy and the encoded PNG; the neural
// path's G-buffer), with room to spare (measured: docs/design.md; docs/usage.md).
constexpr uint64_t kRenderBytesPerPixel = 48;

struct RenderOptions {
    std::string scene;
    std::vector<std::string> outputs;
    std::string asset;
    int spp = 64;
    int width = 0;
    int height = 0;
    int maxDepth = 0;
    int camera = -1;
    uint32_t seed = 0;
    int threads = 0;
    float exposure = 0.0f;
    bool quiet = false;
    NeeMode nee = NeeMode::Power;
    float neeMix = NeeSettings{}.mix;
    uint32_t neeWarmup = NeeSettings{}.warmupSteps;
    int neeQuantum = NeeSettings{}.quantum;
    std::string chosenLight;
    ImportLimits importLimits;
    std::vector<std::string> inserts;
    LightingOptions lighting;
    ViewOptions view;
    bool force = false;
};

int writeOutputs(const RenderOptions& o, const Image& image) {
    try {
        for (const std::string& out : o.outputs) writeImage(out, image, o.exposure);
    } catch (const IoError& e) {
        std::fprintf(stderr, "nrad render: %s\n", e.what());
        return kExitIo;
    }
    return kExitOk;
}

// Primary visibility by Embree, radiance from the asset through the public runtime API.
int renderNeural(const RenderOptions& o, const Scene& scene, const Accel& accel, const Camera& camera,
                 const RenderSettings& settings, const nrad::Asset& asset) {
    NradAssetInfo info;
    if (!scene.insertedObjects.empty() && nradGetAssetInfo(asset.get(), &info) == NRAD_OK && info.volumeNetworks == 0)
        std::fprintf(stderr, "nrad render: %s has no volume networks (bake with --volume-points): the inserted objects are shaded by "
                             "the surfaces' networks, an extrapolation nobody trained\n", o.asset.c_str());
    ProgressBar bar("render", !o.quiet);
    Image image;
    NeuralRenderStats stats;
    NradStatus st = renderThroughAsset(scene, accel, asset.get(), camera, settings, image, &stats,
                                       [&](double f) { bar.update(f); });
    if (st != NRAD_OK) {
        std::fprintf(stderr, "nrad render: %s: evaluation failed: %s\n", o.asset.c_str(), nradStatusString(st));
        return kExitInternal;
    }
    if (int code = writeOutputs(o, image)) return code;
    std::printf("rendered %s through %s: %dx%d, %d spp, %.3f s (thread time: visibility %.3f s, evaluation %.3f s), "
                "%llu evaluations (%.1f M/s per thread), %llu outside the grid, %llu in empty voxels -> %s\n",
                o.scene.c_str(), o.asset.c_str(), settings.width, settings.height, settings.spp, stats.seconds,
                stats.visibilitySeconds, stats.evaluationSeconds, (unsigned long long)stats.evaluations,
                stats.evaluationSeconds > 0 ? 1e-6 * double(stats.evaluations) / stats.evaluationSeconds : 0.0,
                (unsigned long long)stats.outsideGrid, (unsigned long long)stats.emptyVoxel,
                CLI::detail::join(o.outputs, ", ").c_str());
    return kExitOk;
}

int runRender(const RenderOptions& o, CLI::App* cmd) {
    for (const std::string& out : o.outputs)
        if (!isSupportedImagePath(out)) {
            std::fprintf(stderr, "nrad render: %s: unsupported output type (use .exr or .png)\n", out.c_str());
            return kExitUsage;
        }
    {
        std::vector<std::string> outputs = o.outputs;
        if (!o.chosenLight.empty()) outputs.push_back(o.chosenLight);
        if (int code = checkOutputsForCommand("render", outputs)) return code;
    }
    ThreadScope threads(o.threads);
    auto t0 = std::chrono::steady_clock::now();
    Scene scene;
    if (int code = loadSceneForCommand("render", o.scene, o.quiet, scene, o.importLimits)) return code;
    nrad::Asset asset;
    std::string metadata;
    if (!o.asset.empty()) {
        std::string message;
        if (NradStatus st = asset.loadFromFile(o.asset.c_str(), &message); st != NRAD_OK) {
            std::fprintf(stderr, "nrad render: %s\n", message.c_str());
            return kExitBadInput;
        }
        const char* json = nullptr;
        size_t length = 0;
        if (nradGetMetadata(asset.get(), &json, &length) == NRAD_OK && json) metadata.assign(json, length);
    }
    if (int code = applyLightingForCommand("render", o.lighting, lightingFlagsGiven(cmd), cmd->count("--environment") > 0, o.quiet,
                                           scene, metadata)) return code;
    if (!o.asset.empty())
        if (int code = checkAssetSceneForCommand("render", o.asset, metadata, scene, o.force, o.quiet)) return code;
    Camera camera;
    if (int code = chooseCameraForCommand("render", scene, o.camera, o.view, o.quiet, camera)) return code;
    // After the camera: a scene without one is framed as baked, not around the objects placed into it.
    if (int code = insertObjectsForCommand("render", o.inserts, o.importLimits, o.quiet, scene)) return code;
    RenderSettings settings;
    settings.spp = o.spp;
    settings.maxDepth = o.maxDepth;
    settings.seed = o.seed;
    float aspect = camera.aspectRatio > 0.0f ? camera.aspectRatio : 1.0f;
    if (int code = imageSizeForCommand("render", o.width, o.height, aspect, 512, settings.width, settings.height)) return code;
    // Refused up front with the figure, not after the scene is built: the image and its encoded copies.
    if (int code = checkMemoryForCommand("render", uint64_t(settings.width) * uint64_t(settings.height) * kRenderBytesPerPixel,
                                         "a " + std::to_string(settings.width) + " x " + std::to_string(settings.height) + " image"))
        return code;

    Accel accel(scene);
    if (!o.chosenLight.empty() && !isSupportedImagePath(o.chosenLight)) {
        std::fprintf(stderr, "nrad render: %s: unsupported output type (use .exr or .png)\n", o.chosenLight.c_str());
        return kExitUsage;
    }
    if (!o.asset.empty()) return renderNeural(o, scene, accel, camera, settings, asset);
    LightSampler lights(scene);
    auto t1 = std::chrono::steady_clock::now();

    NeeSettings nee;
    nee.mode = o.nee;
    nee.mix = o.neeMix;
    nee.warmupSteps = o.neeWarmup;
    nee.quantum = o.neeQuantum;
    nee.seed = o.seed;
    LightSelector selector(lights, scene.bounds, nee);
    PathTracer tracer(scene, accel, lights, &selector);
    ProgressBar bar("render", !o.quiet);
    RenderStats stats;
    Image image;
    std::string neeSummary;
    if (o.nee == NeeMode::Power && o.chosenLight.empty()) {
        image = tracer.render(camera, settings, &stats, [&](double f) { bar.update(f); });
    } else {
        // Rounds with online training (learned), also used for uniform/power so their times compare.
        OnlineRenderResult r = renderOnline(tracer, &selector, camera, settings, {}, [&](double f) { bar.update(f); });
        image = std::move(r.image);
        stats = r.stats.render;
        char buf[256];
        std::snprintf(buf, sizeof buf,
                      ", light selection %s over %zu lights (%llu warm-up paths, %llu training steps, %.2f s)",
                      neeModeName(o.nee), lights.groupCount(), (unsigned long long)r.stats.warmupPaths,
                      (unsigned long long)r.stats.trainingSteps, r.stats.trainingSeconds);
        neeSummary = buf;
        if (!o.chosenLight.empty()) {
            Image chosen(settings.width, settings.height);
            for (size_t i = 0; i < chosen.pixels.size(); ++i) chosen.pixels[i] = lightGroupColor(r.firstLight[i]);
            try {
                writeImage(o.chosenLight, chosen, 0.0f);
            } catch (const IoError& e) {
                std::fprintf(stderr, "nrad render: %s\n", e.what());
                return kExitIo;
            }
        }
    }
    if (int code = writeOutputs(o, image)) return code;
    double setup = std::chrono::duration<double>(t1 - t0).count();
    std::printf("rendered %s: %dx%d, %d spp, max depth %s, %.2f s (scene setup %.2f s), %.3g samples, %.2f Mrays/s "
                "(%llu camera, %llu extension, %llu shadow), %llu non-finite samples dropped%s -> %s\n",
                o.scene.c_str(), settings.width, settings.height, settings.spp,
                settings.maxDepth ? std::to_string(settings.maxDepth).c_str() : "unbounded", stats.seconds, setup,
                double(stats.samples), stats.raysPerSecond() * 1e-6, (unsigned long long)stats.rays.primary,
                (unsigned long long)stats.rays.extension, (unsigned long long)stats.rays.shadow,
                (unsigned long long)stats.rays.nonFiniteSamples, neeSummary.c_str(),
                CLI::detail::join(o.outputs, ", ").c_str());
    return kExitOk;
}

}  // namespace

std::function<int()> addRenderCommand(CLI::App& app) {
    auto opts = std::make_shared<RenderOptions>();
    CLI::App* cmd = app.add_subcommand("render", "Path trace a reference image of a glTF scene");
    cmd->add_option("scene", opts->scene, "glTF 2.0 scene (.gltf or .glb)")->required();
    cmd->add_option("-o,--output", opts->outputs, "Output image: .exr (linear float) or .png (sRGB); repeat for several")
        ->required()
        ->allow_extra_args(false);
    cmd->add_option("--asset", opts->asset, "Render through this .nrad asset (first hit + network) instead of path tracing");
    cmd->add_option("--spp", opts->spp, "Samples per pixel (default 64; 4 is the paper's for --asset)")->check(CLI::Range(1, 1 << 24));
    cmd->add_option("--width", opts->width, "Image width (default 512, or from --height and the camera aspect)")
        ->check(CLI::Range(1, 1 << 15));
    cmd->add_option("--height", opts->height, "Image height (default from the width and the camera aspect)")
        ->check(CLI::Range(1, 1 << 15));
    cmd->add_option("--max-depth", opts->maxDepth, "Maximum path length in segments; 0 = unbounded")
        ->check(CLI::Range(0, 1 << 20));
    cmd->add_option("--camera", opts->camera, "Camera index (default: the first; auto-framing if none)")
        ->check(CLI::NonNegativeNumber);
    cmd->add_option("--seed", opts->seed, "Seed of the quasi-random sequence");
    cmd->add_option("--threads", opts->threads, "Worker threads; 0 = all")->check(CLI::Range(0, 4096));
    cmd->add_option("--exposure", opts->exposure, "PNG exposure in stops")->check(finiteRange(-64.0, 64.0));
    cmd->add_option("--nee", opts->nee,
                    "Light selection for next event estimation: power (default), uniform, or learned (a network "
                    "trained while rendering; docs/lights.md)")
        ->transform(CLI::CheckedTransformer(
            std::map<std::string, NeeMode>{{"power", NeeMode::Power}, {"uniform", NeeMode::Uniform},
                                           {"learned", NeeMode::Learned}},
            CLI::ignore_case));
    cmd->add_option("--nee-mix", opts->neeMix,
                    "Learned selection: share of the uniform choice among the lights that can contribute (default 0.05)")
        ->check(finiteRange(0.001, 1.0));
    cmd->add_option("--nee-warmup", opts->neeWarmup,
                    "Learned selection: training steps on camera paths traced before the image, which then renders "
                    "with the network fixed (default 1024); 0 = train throughout the render and keep every sample "
                    "(the paper's variant)")
        ->check(CLI::Range(0, 1 << 24));
    cmd->add_option("--nee-quantum", opts->neeQuantum,
                    "Learned selection: round the probabilities to whole units of 1/Q, at least one per light that "
                    "can contribute (default 64: best from about 32 spp on); 0 = no rounding (better for a few spp)")
        ->check(CLI::Range(0, 1 << 20));
    cmd->add_option("--chosen-light", opts->chosenLight,
                    "Also write a false-colour image of the light chosen at each pixel's first hit (.png or .exr)");
    addLightingOptions(cmd, opts->lighting);
    addViewOptions(cmd, opts->view);
    addImportOptions(cmd, opts->importLimits);
    addInsertOption(cmd, opts->inserts);
    cmd->add_flag("--force", opts->force, "--asset: use an asset even if it was baked from another scene or lighting");
    cmd->add_flag("-q,--quiet", opts->quiet, "No progress or import summary on stderr");
    return [opts, cmd]() { return runRender(*opts, cmd); };
}

}  // namespace nrad
