// `nrad validate`: the asset against a path-traced reference, error against run time, an HTML report.
#include <algorithm>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <memory>
#include <string>

#include <nlohmann/json.hpp>
#include <nrad/nrad.hpp>

#include "baker/cmd/commands.h"
#include "baker/util/atomic_file.h"
#include "baker/util/threads.h"
#include "baker/validate/report.h"
#include "baker/validate/validate.h"

namespace nrad {

namespace {

// Bytes a validation holds per pixel at its peak: an estimate, not a measurement (about a dozen float images
// held at once: reference, neural, baseline, the curve's, the error maps; with their encoded copies).
constexpr uint64_t kValidateBytesPerPixel = 200;

struct ValidateOptions {
    std::string scene, asset, output, bakeStats, cacheDir, reference;
    int width = 512, height = 0, camera = -1, referenceSpp = 512, maxDepth = 0, neuralSpp = 4, curveMaxSpp = 64, threads = 0;
    uint32_t seed = 0;
    uint32_t baselinePointsPerProbe = kBaselinePointsPerProbe, baselinePathsPerProbe = kBaselinePathsPerProbe;
    float exposure = 0.0f;
    bool noCache = false, noBaseline = false, quiet = false, force = false;
    LightingOptions lighting;
    ViewOptions view;
    ImportLimits importLimits;
    std::vector<std::string> inserts;
};

// $XDG_CACHE_HOME/nrad, else $HOME/.cache/nrad, else a folder beside the report (not inside: the report folder
// is replaced whole by the next validation).
std::string defaultCacheDir(const std::string& output) {
    if (const char* x = std::getenv("XDG_CACHE_HOME"); x && *x) return (std::filesystem::path(x) / "nrad").string();
    if (const char* h = std::getenv("HOME"); h && *h) return (std::filesystem::path(h) / ".cache" / "nrad").string();
    return output + "-cache";
}

std::string fmtG(double v) {
    char s[32];
    std::snprintf(s, sizeof s, "%.3g", v);
    return s;
}

// --bake-stats: the JSON object `nrad bake --stats` wrote (into `out`), or an error.
int readBakeStats(const ValidateOptions& o, nlohmann::json& out) {
    if (o.bakeStats.empty()) return kExitOk;
    std::ifstream f(o.bakeStats);
    if (f) out = nlohmann::json::parse(f, nullptr, false);
    if (!f || out.is_discarded() || !out.is_object()) {
        std::fprintf(stderr, "nrad validate: %s: %s\n", o.bakeStats.c_str(),
                     !f ? "cannot open file" : "not the JSON object `nrad bake --stats` writes");
        return kExitBadInput;
    }
    return kExitOk;
}

// The run's settings from the options (the camera and the image size are chosen before).
void copyRunSettings(const ValidateOptions& o, ValidateSettings& s) {
    s.referenceSpp = o.referenceSpp;
    s.maxDepth = o.maxDepth;
    s.neuralSpp = o.neuralSpp;
    s.curveMaxSpp = o.curveMaxSpp;
    s.seed = o.seed;
    s.exposure = o.exposure;
    s.baseline = !o.noBaseline;
    s.baselinePointsPerProbe = o.baselinePointsPerProbe;
    s.baselinePathsPerProbe = o.baselinePathsPerProbe;
    s.referenceImage = o.reference;
    s.cacheDir = o.noCache ? std::string() : (o.cacheDir.empty() ? defaultCacheDir(o.output) : o.cacheDir);
}

// The summary's numbers: the headline, the baseline, where the error is, what the eye sees, by material.
void printHeadline(const ValidateOptions& o, const ValidationResult& r) {
    std::printf("validated %s against %s (%dx%d): neural relMSE %.4g, RMSE %.4g, PSNR %.2f dB, render %.3g s (evaluation %.3g s)\n",
                o.asset.c_str(), o.scene.c_str(), r.width, r.height, r.neural.metrics.relMse, r.neural.metrics.rmse,
                r.neural.metrics.psnr, r.neural.seconds, r.neural.evaluationSeconds);
    if (r.baseline)
        std::printf("  SH probe baseline (%zu bytes, neural %zu bytes): relMSE %.4g -> %s is better overall\n", r.baseline->bytes,
                    r.neural.bytes, r.baseline->metrics.relMse,
                    r.neural.metrics.relMse <= r.baseline->metrics.relMse ? "neural" : "the SH baseline");
    {
        const MethodResult& n = r.neural;
        std::printf("  where: worst 1%% of pixels hold %.1f%% of the relMSE; relative error median %.3g, 99th percentile %.3g;"
                    " relMSE", 100.0 * n.distribution.worst1PercentShare, n.distribution.medianRelativeError,
                    n.distribution.p99RelativeError);
        for (size_t k = 0; k < n.byRegion.size(); ++k)
            std::printf("%s %s %.3g (%.1f%%)", k ? "," : "", kRegionNames[k], n.byRegion[k].relMse, 100.0 * n.byRegion[k].shareOfImage);
        std::printf("; seams: relMSE across shared faces %.3g at %zu points\n", r.seams.relMse, r.seams.points);
        // What the eye sees: the light's shape and colour on the surfaces (the SH probes' in brackets).
        const bool b = r.baseline.has_value();
        const MethodResult* sh = b ? &*r.baseline : nullptr;
        std::printf("  what the eye sees: SSIM %.4f%s at the viewer's exposure (%+.1f stops)\n", n.metrics.ssim,
                    b ? (" [" + fmtG(sh->metrics.ssim) + "]").c_str() : "", n.metrics.ssimExposure);
        std::printf("  what the eye sees (%zu surface pixels): relMSE %.3g%s; %dx%d-pixel blocks (%zu): luminance error rms %.3g, "
                    "worst %.3g%s%s%s; tint rms %.3g, worst %.3g (chroma %.3g, reference %.3g); steps at cell faces (%zu): rms %.3g, "
                    "worst %.3g\n",
                    n.surfaces.pixels, n.surfaces.relMse, b ? (" [" + fmtG(sh->surfaces.relMse) + "]").c_str() : "", n.blocks.blockSize,
                    n.blocks.blockSize, n.blocks.blocks, n.blocks.rms, n.blocks.worst,
                    n.blocks.worstX >= 0 ? (" (" + std::string(n.blocks.worstSigned < 0.0 ? "darker" : "brighter") + ", at pixel " +
                                            std::to_string(n.blocks.worstX) + "," + std::to_string(n.blocks.worstY) + ")").c_str() : "",
                    b ? (" [" + fmtG(sh->blocks.rms) + ", " + fmtG(sh->blocks.worst) + "]").c_str() : "",
                    r.referenceBlockNoise >= 0.0 ? (" (the reference's own noise: about " + fmtG(r.referenceBlockNoise) + " rms)").c_str() : "", n.blocks.tintRms,
                    n.blocks.tintWorst, n.blocks.chroma, n.blocks.referenceChroma, n.steps.faces, n.steps.rms, n.steps.worst);
        // By material, largest neural share first (the five largest; report.json has them all).
        const std::vector<size_t> order = materialsByNeuralShare(r);
        if (!order.empty()) {
            std::printf("  by material (relMSE, share%s):", r.baseline ? "; SH probes' relMSE" : "");
            for (size_t i = 0; i < order.size() && i < 5; ++i) {
                const size_t k = order[i];
                std::printf("%s %s %.3g (%.1f%%", i ? "," : "", r.materialNames[k].c_str(), n.byMaterial[k].relMse,
                            100.0 * n.byMaterial[k].shareOfImage);
                if (r.baseline && k < r.baseline->byMaterial.size()) std::printf("; %.3g", r.baseline->byMaterial[k].relMse);
                std::printf(")");
            }
            if (order.size() > 5) std::printf(", %zu more", order.size() - 5);
            std::printf("\n");
        }
    }
}

// The summary's notes: bias, the path tracer at equal error, the bake's time, the reference, the report.
void printNotesAndTimes(const ValidationResult& r, const nlohmann::json& bakeStats, const std::string& html) {
    for (const std::string& note : r.biasNotes) std::printf("  bias: %s\n", note.c_str());
    if (referenceIsBlack(r))
        std::printf("  path tracer at equal error: none: %s\n", kNoLightToCompare);
    else
        std::printf("  path tracer at equal error: %.3g s%s = %.3gx the network evaluation, %.3gx the whole neural render\n",
                    r.neural.equalErrorSeconds, r.neural.equalErrorExtrapolated ? " (extrapolated)" : "",
                    r.neural.speedupOverEvaluation, r.neural.speedupOverRender);
    if (bakeStats.is_object() && bakeStats.contains("seconds") && bakeStats["seconds"].is_object()) {
        double total = 0.0;
        for (auto& [k, v] : bakeStats["seconds"].items())
            if (v.is_number()) total += v.get<double>();
        std::printf("  bake: %.2f s, %s bytes\n", total, bakeStats.value("asset_bytes", nlohmann::json("?")).dump().c_str());
    }
    std::string noise;
    if (r.referenceNoise >= 0.0) {
        char text[160];
        std::snprintf(text, sizeof text, "; its own noise adds about %.3g to every relMSE above (the neural image against the truth: "
                      "about %.3g)", r.referenceNoise, std::max(0.0, r.neural.metrics.relMse - r.referenceNoise));
        noise = text;
    }
    std::printf("  reference: %s%s%s\n  report: %s\n", r.referenceSource.c_str(),
                r.referenceSeconds > 0 ? (" (" + std::to_string(r.referenceSeconds) + " s)").c_str() : "", noise.c_str(), html.c_str());
}

int runValidate(const ValidateOptions& o, CLI::App* cmd) {
    nlohmann::json bakeStats;
    if (int code = readBakeStats(o, bakeStats)) return code;
    if (int code = checkOutputsForCommand("validate", {}, {o.output})) return code;
    ThreadScope threads(o.threads);
    Scene scene;
    if (int code = loadSceneForCommand("validate", o.scene, o.quiet, scene, o.importLimits)) return code;
    nrad::Asset asset;
    std::string message;
    if (asset.loadFromFile(o.asset.c_str(), &message) != NRAD_OK) {
        std::fprintf(stderr, "nrad validate: %s\n", message.c_str());
        return kExitBadInput;
    }
    std::string metadata;
    {
        const char* json = nullptr;
        size_t length = 0;
        if (nradGetMetadata(asset.get(), &json, &length) == NRAD_OK && json) metadata.assign(json, length);
    }
    if (int code = applyLightingForCommand("validate", o.lighting, lightingFlagsGiven(cmd), cmd->count("--environment") > 0, o.quiet,
                                           scene, metadata)) return code;
    if (int code = checkAssetSceneForCommand("validate", o.asset, metadata, scene, o.force, o.quiet)) return code;
    if (!scene.hasLight()) {
        // Every image would be black and every ratio 0 / 0.
        std::fprintf(stderr, "nrad validate: %s: nothing lights the scene (no emitter of positive power, no punctual light, "
                             "no environment): there is no error to measure; give it an --environment\n", o.scene.c_str());
        return kExitBadInput;
    }
    ValidateSettings s;
    if (int code = chooseCameraForCommand("validate", scene, o.camera, o.view, o.quiet, s.camera)) return code;
    // After the camera: a scene without one is framed as baked, not around the objects placed into it.
    if (int code = insertObjectsForCommand("validate", o.inserts, o.importLimits, o.quiet, scene)) return code;
    const float aspect = s.camera.aspectRatio > 0.0f ? s.camera.aspectRatio : 1.0f;
    if (int code = imageSizeForCommand("validate", o.width, o.height, aspect, 512, s.width, s.height)) return code;
    if (int code = checkMemoryForCommand("validate", uint64_t(s.width) * uint64_t(s.height) * kValidateBytesPerPixel,
                                         "validating at " + std::to_string(s.width) + " x " + std::to_string(s.height)))
        return code;
    copyRunSettings(o, s);
    ValidationResult r;
    try {
        r = runValidation(scene, o.scene, asset.get(), o.asset, s, [&](const std::string& line) {
            if (!o.quiet) std::fprintf(stderr, "%s\n", line.c_str());
        });
    } catch (const IoError& e) {
        std::fprintf(stderr, "nrad validate: %s\n", e.what());
        return kExitIo;
    } catch (const std::exception& e) {
        std::fprintf(stderr, "nrad validate: %s\n", e.what());
        return kExitBadInput;
    }
    std::string html;
    try {
        html = writeReport(r, bakeStats, o.output);
    } catch (const IoError& e) {
        std::fprintf(stderr, "nrad validate: %s\n", e.what());
        return kExitIo;
    }
    printHeadline(o, r);
    printNotesAndTimes(r, bakeStats, html);
    return kExitOk;
}

}  // namespace

std::function<int()> addValidateCommand(CLI::App& app) {
    auto o = std::make_shared<ValidateOptions>();
    CLI::App* cmd = app.add_subcommand("validate", "Compare an asset with a path-traced reference: error against run time, HTML report");
    cmd->add_option("scene", o->scene, "glTF 2.0 scene the asset was baked from")->required();
    cmd->add_option("asset", o->asset, "Neural radiance asset (.nrad)")->required();
    cmd->add_option("-o,--output", o->output, "Report folder (report.html, report.json, images, plots)")->required();
    cmd->add_option("--bake-stats", o->bakeStats, "The bake's `nrad bake --stats` JSON: its training curve and phase times join the report");
    cmd->add_option("--width", o->width, "Image width (default 512)")->check(CLI::Range(1, 1 << 14));
    cmd->add_option("--height", o->height, "Image height (default from the width and the camera aspect)")->check(CLI::Range(1, 1 << 14));
    cmd->add_option("--camera", o->camera, "Camera index (default: the first)")->check(CLI::NonNegativeNumber);
    cmd->add_option("--reference-spp", o->referenceSpp, "Paths per pixel of the reference (default 512)")->check(CLI::Range(1, 1 << 24));
    cmd->add_option("--max-depth", o->maxDepth, "Path length of reference and convergence curve; 0 = unbounded (default 0: the full light transport; a length is reported as a biased reference)")
        ->check(CLI::Range(0, 1 << 20));
    cmd->add_option("--spp", o->neuralSpp, "Primary samples per pixel through the asset (default 4)")->check(CLI::Range(1, 1 << 16));
    cmd->add_option("--curve-max-spp", o->curveMaxSpp, "The path tracer's convergence curve goes 1, 2, 4, ... up to this (default 64)")
        ->check(CLI::Range(1, 1 << 20));
    cmd->add_option("--seed", o->seed, "Seed of the reference (the curve uses seed + 1)");
    cmd->add_option("--reference", o->reference, "Use this EXR as the reference instead of rendering one");
    cmd->add_option("--cache-dir", o->cacheDir, "Cache of references and SH baselines (default $XDG_CACHE_HOME/nrad or ~/.cache/nrad)");
    cmd->add_flag("--no-cache", o->noCache, "Neither read nor write the cache (references, SH baselines)");
    cmd->add_flag("--no-baseline", o->noBaseline, "Leave out the SH-probe baseline");
    cmd->add_option("--baseline-points-per-probe", o->baselinePointsPerProbe,
                    "The SH baseline's training points: the bake's first max(" + std::to_string(kBaselineMinPoints) +
                        ", this x probes); 0 = all of the bake's (default " + std::to_string(kBaselinePointsPerProbe) + ")");
    cmd->add_option("--baseline-paths-per-probe", o->baselinePathsPerProbe,
                    "The SH baseline's traced paths: at most max(" + std::to_string(kBaselineMinPaths) +
                        ", this x probes), fewer paths per point first; 0 = the bake's paths per point (default " +
                        std::to_string(kBaselinePathsPerProbe) + ")");
    cmd->add_option("--exposure", o->exposure, "Exposure in stops for PNGs and PSNR")->check(finiteRange(-64.0, 64.0));
    cmd->add_option("--threads", o->threads, "Worker threads; 0 = all")->check(CLI::Range(0, 4096));
    addLightingOptions(cmd, o->lighting);
    addViewOptions(cmd, o->view);
    addImportOptions(cmd, o->importLimits);
    addInsertOption(cmd, o->inserts);
    cmd->add_flag("--force", o->force, "Validate an asset even if it was baked from another scene or lighting");
    cmd->add_flag("-q,--quiet", o->quiet, "No progress or import summary on stderr");
    return [o, cmd]() { return runValidate(*o, cmd); };
}

}  // namespace nrad
