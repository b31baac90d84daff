// `nrad bake`: glTF scene -> .nrad asset.
#include <algorithm>
#include <cctype>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <map>
#include <memory>
#include <set>
#include <thread>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "baker/bake/baker.h"
#include "baker/cmd/commands.h"
#include "baker/scene/gltf_loader.h"
#if defined(NRAD_HAVE_MPI)
#include "baker/dist/mpi_group.h"
#endif
#include "baker/util/atomic_file.h"
#include "baker/util/hash.h"
#include "baker/util/progress.h"
#include "baker/util/threads.h"

namespace nrad {

namespace {

// The settings' own defaults, made once (temporaries of these structs in member initialisers make GCC 12
// report its own vector destructors as maybe-uninitialised).
const BakeSettings& defaults() {
    static const BakeSettings s;
    return s;
}

std::string joinFloats(const std::vector<float>& v) {
    std::string s;
    for (float x : v) {
        char b[32];
        std::snprintf(b, sizeof b, "%g", double(x));
        s += (s.empty() ? "" : ",") + std::string(b);
    }
    return s;
}

// Comma-separated finite values >= 0, 1 to 8 of them.
bool parseFloats(const std::string& s, std::vector<float>& out) {
    out.clear();
    for (const std::string& part : splitCommas(s)) {
        char* end = nullptr;
        float v = std::strtof(part.c_str(), &end);
        if (part.empty() || *end != '\0' || !std::isfinite(v) || v < 0.0f) return false;
        out.push_back(v);
    }
    return out.size() <= 8;
}

// "3" for a cubic grid, else "NxMxK".
std::string gridText(const glm::uvec3& g) {
    if (g.x == g.y && g.y == g.z) return std::to_string(g.x);
    return std::to_string(g.x) + "x" + std::to_string(g.y) + "x" + std::to_string(g.z);
}

std::string hiddenText(const std::vector<int>& widths) {
    std::string s;
    for (int w : widths) s += (s.empty() ? "" : ",") + std::to_string(w);
    return s;
}

const char* encodingName(format::WeightEncoding e) { return e == format::WeightEncoding::Float32 ? "fp32" : "fp16"; }

// The command line of a bake: where its output goes and how it runs, then its settings, each starting at the
// library's default (BakeSettings) as the flags' text; bakeSettingsTable() binds them to their flags and keys.
struct BakeOptions {
    std::string scene, output, config, stats, saveGenerations;
    std::string shard, traced;  // --shard K/N, --traced DIR (shard_bake: not settings of the asset)
    bool traceOnly = false;
    int threads = 0;
    bool quiet = false, dumpConfig = false;
    std::string preset;  // --preset NAME: settings under the config file's and the flags'

    std::string grid = gridText(defaults().grid), hidden = hiddenText(defaults().train.shape.hidden);
    std::string loss = lossName(defaults().train.loss), encoding = encodingName(defaults().encoding);
    uint32_t points = defaults().samples.points, paths = defaults().samples.paths, seed = defaults().samples.seed;
    uint32_t minSamples = defaults().samples.minSamplesPerVoxel, noisyPaths = defaults().samples.extraPathsFactor;
    std::string nee = neeModeName(defaults().nee.mode);
    int maxDepth = defaults().samples.maxDepth, epochs = defaults().train.epochs, batch = defaults().train.batchSize;
    int patience = defaults().train.patience, raceEpochs = defaults().train.raceEpochs, restarts = defaults().train.restarts;
    float learningRate = defaults().train.learningRate, blendBand = defaults().blendBand;
    float noisyError = defaults().samples.noisyRelativeError;
    float epochAverage = defaults().train.epochAverage;
    std::string weightDecay = joinFloats(defaults().train.weightDecays);
    std::string budget;  // bytes, with an optional K / M suffix (x1024); empty: the uniform grid
    uint32_t levels = defaults().partition.levels, minLeafSamples = defaults().partition.minLeafSamples;
    uint32_t volumePoints = 0, volumePaths = defaults().volume.paths;  // 0 points: no volume networks
    bool volumeGlossy = false, raceAll = defaults().train.raceAll;
    bool noMetadata = !defaults().metadata, noDemodulate = !defaults().train.demodulate, noWallSplits = !defaults().walls.enabled;
    LightingOptions lighting = bakeLighting();
    std::string training = trainingMethodName(defaults().training);
    IntegralSettings integral = defaults().integral;
    std::string generationLr = joinFloats({defaults().integral.learningRate, defaults().integral.finalLearningRate});
    ImportLimits importLimits;

    // Mixed lighting by default: the engine draws the direct light of sharp punctual lights and a sharp sun,
    // the asset holds the rest. Baked, a sun's direct light is a smear (docs/lights.md, docs/results.md).
    static LightingOptions bakeLighting() {
        LightingOptions l;
        l.runtimeDirect = "auto";
        return l;
    }
};

bool parseGrid(const std::string& s, glm::uvec3& out) {
    unsigned a, b, c;
    char x1, x2, rest;
    if (std::sscanf(s.c_str(), "%u%c%u%c%u%c", &a, &x1, &b, &x2, &c, &rest) == 5 && x1 == 'x' && x2 == 'x') {
        out = {a, b, c};
    } else if (std::sscanf(s.c_str(), "%u%c", &a, &rest) == 1) {
        out = {a, a, a};
    } else {
        return false;
    }
    return out.x >= 1 && out.y >= 1 && out.z >= 1 && out.x <= 256 && out.y <= 256 && out.z <= 256;
}

bool parseHidden(const std::string& s, std::vector<int>& out) {
    out.clear();
    for (const std::string& part : splitCommas(s)) {
        char* end = nullptr;
        long v = std::strtol(part.c_str(), &end, 10);
        if (part.empty() || *end != '\0' || v < 1 || v > long(format::kMaxHiddenWidth)) return false;
        out.push_back(int(v));
    }
    return out.size() <= format::kMaxHiddenLayers;
}

// "65536", "64K", "64KB", "1M", "1MB" (K = 1024 bytes); at most 4 GB.
bool parseBytes(const std::string& s, uint64_t& out) {
    char* end = nullptr;
    const double v = std::strtod(s.c_str(), &end);
    if (s.empty() || end == s.c_str() || !(v > 0.0)) return false;
    std::string unit(end);
    for (char& c : unit) c = char(std::toupper(static_cast<unsigned char>(c)));
    double scale = 1.0;
    if (unit == "K" || unit == "KB" || unit == "KIB") scale = 1024.0;
    else if (unit == "M" || unit == "MB" || unit == "MIB") scale = 1024.0 * 1024.0;
    else if (!unit.empty() && unit != "B") return false;
    const double bytes = std::floor(v * scale);
    if (!(bytes >= 1.0 && bytes <= 4294967296.0)) return false;
    out = uint64_t(bytes);
    return true;
}

// --nee's names (also "nee" in --config).
const std::map<std::string, NeeMode>& neeModes() {
    static const std::map<std::string, NeeMode> m{{"power", NeeMode::Power}, {"uniform", NeeMode::Uniform}, {"learned", NeeMode::Learned}};
    return m;
}

bool parseNeeMode(std::string name, NeeMode& out) {
    for (char& c : name) c = char(std::tolower(static_cast<unsigned char>(c)));
    const auto it = neeModes().find(name);
    if (it == neeModes().end()) return false;
    out = it->second;
    return true;
}

int usage(const std::string& what) {
    std::fprintf(stderr, "nrad bake: %s\n", what.c_str());
    return kExitUsage;
}

// Held-out relMSE above which the bake warns (a voxel's network against its own held-out samples; the bundled
// boxes stay far below, a sunlit interior baked with its sun reads mean 27.9, worst 162).
constexpr double kLargeHeldOutMean = 1.0, kLargeHeldOutWorst = 5.0;

// Every setting of `nrad bake`: its --config key, its flag, its help; its default is the option's value now.
SettingsTable bakeSettingsTable(BakeOptions& o) {
    SettingsTable t;
    t.add("--grid", &o.grid, "Voxel grid: N (cubic) or NxMxK");
    t.add("--points", &o.points, "Surface points (training samples) before the per-voxel floor")
        .describeDefault("0: automatic: " + std::to_string(kBasePoints) + ", and as many per cell on grids finer than 27 cells; with "
                         "--budget " + std::to_string(kPointsPerNetwork) + " per network it pays for; with --training integral " +
                         std::to_string(kIntegralPointsPerCell) + " per cell, at least " + std::to_string(kIntegralMinPoints) +
                         "; at most " + std::to_string(kMaxAutomaticPoints));
    t.add("--paths", &o.paths, "Paths per training sample")
        .describeDefault("0: automatic: " + std::to_string(kMonteCarloPaths) + "; " + std::to_string(kIntegralStartPaths) +
                         " for the Monte Carlo start of --training integral");
    t.add("--noisy-paths", &o.noisyPaths,
          "Points whose target's relative standard error over their paths exceeds --noisy-error get the paths that bring it "
          "there, up to this many times the paths; 1: off, which takes the glossy box from relMSE 0.0037 to 0.0085");
    t.add("--noisy-error", &o.noisyError,
          "The bound of --noisy-paths: a point whose target's relative standard error exceeds it gets the paths that bring "
          "it there")
        .checkedBy([](CLI::Option* p) { p->check(finiteRange(0.01, 1.0)); });
    t.add("--nee", &o.nee,
          "Light selection of the training paths: power, uniform, or learned (a selection network trained on warm-up paths "
          "from the training points first)")
        .checkedBy([](CLI::Option* p) { p->transform(CLI::IsMember(neeModes(), CLI::ignore_case)); });
    t.add("--max-depth", &o.maxDepth,
          "Path length in segments for training radiance; 0 = unbounded, with Russian roulette (the full light transport; a "
          "length cuts off the light of longer paths, a bias validate reports)");
    t.add("--hidden", &o.hidden, "Hidden layer widths, comma-separated");
    t.add("--epochs", &o.epochs, "Maximum training epochs per voxel");
    t.add("--batch-size", &o.batch, "Mini-batch size");
    t.add("--patience", &o.patience, "Stop a voxel after this many epochs without a better held-out error");
    t.add("--learning-rate", &o.learningRate, "Adam learning rate at the start");
    t.add("--loss", &o.loss,
          "l2, relative-l2, symmetric-relative-l2, symmetric-relative-exp or log-l2 (the volume's networks train with "
          "symmetric-relative-exp where the surfaces' is relative-l2)");
    t.add("--encoding", &o.encoding, "Weight encoding: fp16 or fp32");
    t.add("--min-samples-per-voxel", &o.minSamples, "Floor of samples for a voxel with surface");
    t.add("--training", &o.training,
          "monte-carlo (each target from --paths full paths) or integral (within the integral equation: a short Monte Carlo "
          "start of --points points and --paths paths, then rounds of fresh points whose targets are --bounces bounces with "
          "the networks for the rest of the path; docs/training.md)");
    t.add("--generations", &o.integral.generations, "Integral training: rounds after the Monte Carlo start");
    t.add("--generation-points", &o.integral.points, "Integral training: fresh points per round")
        .describeDefault("0: automatic: 2000 per network, at least 50000");
    t.add("--generation-paths", &o.integral.paths, "Integral training: target estimates per point in a round");
    t.add("--generation-epochs", &o.integral.epochs, "Integral training: passes over each round's samples");
    t.add("--generation-lr", &o.generationLr, "Integral training: learning rate of the first and the last round");
    t.add("--average-decay", &o.integral.averageDecay,
          "Integral training: per-step decay of the networks' moving average, 0 = none");
    t.add("--start-epochs", &o.integral.startEpochs, "Integral training: at most this many epochs for the Monte Carlo start");
    t.add("--start-restarts", &o.integral.startRestarts,
          "Integral training: initialisations of each start network, the lowest held-out error kept")
        .describeDefault("0: 4 with 32 rounds or more, else 1");
    t.add("--bounces", &o.integral.bounces, "Integral training: bounces before the networks stand in");
    t.add("--weight-decay", &o.weightDecay,
          "L2 penalties to choose from per voxel by held-out error, each divided by the voxel's training samples; "
          "0 = unregularised");
    t.add("--restarts", &o.restarts,
          "Initialisations of each network per --weight-decay value, the lowest held-out error kept (1 to 64; integral "
          "training's start: --start-restarts)");
    t.add("--race-epochs", &o.raceEpochs,
          "With several --restarts: after this many epochs each --weight-decay value's start with the lowest held-out "
          "error so far trains on alone, the others stop, and the decays' survivors are compared at their ends; "
          "0 = every candidate trains to its end");
    t.add("--race-all", &o.raceAll,
          "The race compares every candidate (--weight-decay values x --restarts) instead of each decay's starts");
    t.add("--epoch-average", &o.epochAverage,
          "Decay per epoch (0 to 0.99) of the parameters' moving average that each epoch's held-out check judges and the "
          "training keeps; 0 = the parameters themselves");
    t.add("--blend-band", &o.blendBand,
          "Half-width in voxels of the band around voxel faces where neighbouring networks blend, 0 to 0.5; 0 = none");
    t.add("--budget", &o.budget,
          "Asset size in bytes (suffix K or M, 1024-based): an adaptive kd-tree partition refined where it reduces the "
          "expected error most per byte, instead of the uniform --grid (docs/usage.md)");
    t.add("--levels", &o.levels, "With --budget: the finest cell is 2^-levels of the scene's longest axis");
    t.add("--min-leaf-samples", &o.minLeafSamples, "With --budget: training samples a leaf with surface keeps at least");
    t.add("--seed", &o.seed, "Seed (sampling, split, initialisation, order)");
    addImportSettings(t, o.importLimits);
    t.add("--volume-points", &o.volumePoints,
          "Also bake the light in the volume for receivers not in the bake (moving objects): points tried per cell "
          "(about 1000); 0: none");
    t.add("--volume-paths", &o.volumePaths, "With --volume-points: paths per volume point");
    t.add("--volume-glossy", &o.volumeGlossy,
          "With --volume-points: also the volume's glossy response (what a glossy receiver reflects towards a viewer; "
          "docs/usage.md), networks of the same cells");
    t.add("--no-metadata", &o.noMetadata, "Leave out the asset's JSON metadata section");
    t.add("--no-wall-splits", &o.noWallSplits,
          "Without --budget: keep the grid's cells whole where a wall divides one (by default such a cell is split at the "
          "wall, so that no network holds a lit and a dark room; docs/usage.md)");
    t.add("--no-demodulate", &o.noDemodulate,
          "Networks learn the scattered radiance itself, not divided by the surface's reflectance");
    addLightingSettings(t, o.lighting);
    return t;
}

// A config file supplies defaults; flags given on the command line win. Unknown keys are refused. `given`: the
// keys the file gave.
int readConfig(BakeOptions& o, CLI::App* cmd, std::set<std::string>& given) {
    try {
        std::ifstream f(o.config);
        if (!f) throw std::runtime_error("cannot open file");
        const nlohmann::json cfg = nlohmann::json::parse(f);
        if (!cfg.is_object()) throw std::runtime_error("not a JSON object");
        given = bakeSettingsTable(o).readConfig(cfg, cmd);
    } catch (const std::exception& e) {
        std::fprintf(stderr, "nrad bake: %s: %s\n", o.config.c_str(), e.what());
        return kExitBadInput;
    }
    return kExitOk;
}

// The grid, the networks and their training.
int networkSettings(const BakeOptions& o, BakeSettings& s) {
    if (!parseGrid(o.grid, s.grid)) return usage("--grid " + o.grid + ": expected N or NxMxK with 1..256 voxels per axis");
    if (!parseHidden(o.hidden, s.train.shape.hidden))
        return usage("--hidden " + o.hidden + ": expected widths 1..256, comma-separated, at most 8 layers");
    if (!parseLoss(o.loss, s.train.loss)) return usage("--loss " + o.loss + ": expected l2, relative-l2, symmetric-relative-l2, symmetric-relative-exp or log-l2");
    if (o.encoding == "fp16")
        s.encoding = format::WeightEncoding::Float16;
    else if (o.encoding == "fp32")
        s.encoding = format::WeightEncoding::Float32;
    else
        return usage("--encoding " + o.encoding + ": expected fp16 or fp32");
    if (o.noisyPaths < 1 || o.noisyPaths > 64) return usage("--noisy-paths: expected 1 (off) to 64");
    if (o.epochs < 1 || o.batch < 1 || o.patience < 1 || o.maxDepth < 0 || !(o.learningRate > 0.0f) || o.raceEpochs < 0)
        return usage("--epochs, --batch-size, --patience and --learning-rate must be positive, --max-depth and --race-epochs >= 0");
    if (o.restarts < 1 || o.restarts > 64) return usage("--restarts must be 1 to 64");
    if (!(o.epochAverage >= 0.0f && o.epochAverage <= 0.99f)) return usage("--epoch-average must be between 0 and 0.99");
    if (!(o.blendBand >= 0.0f && o.blendBand <= format::kMaxBlendBand))
        return usage("--blend-band: expected 0 (no blending) to 0.5 voxels");
    s.blendBand = o.blendBand;
    if (!parseFloats(o.weightDecay, s.train.weightDecays))
        return usage("--weight-decay " + o.weightDecay + ": expected 1 to 8 comma-separated values >= 0");
    return kExitOk;
}

// The budget and the adaptive partition.
int partitionSettings(const BakeOptions& o, BakeSettings& s) {
    if (!o.budget.empty() && !parseBytes(o.budget, s.partition.budgetBytes))
        return usage("--budget " + o.budget + ": expected a size in bytes, optionally with K or M (1024-based), e.g. 64K");
    if (s.partition.budgetBytes > 0) {  // refused before any work when not even one network fits
        const uint64_t smallest = format::encodedSize(bakeTopology(s), 1, 1, 0);
        if (s.partition.budgetBytes < smallest)
            return usage("--budget " + o.budget + ": below the smallest asset of one network (" + std::to_string(smallest) + " bytes)");
    }
    if (o.levels < 1 || o.levels > 10) return usage("--levels: expected 1 to 10 (2^levels voxels along the longest axis)");
    if (o.minLeafSamples < 16) return usage("--min-leaf-samples: expected at least 16");
    s.partition.levels = o.levels;
    s.partition.minLeafSamples = o.minLeafSamples;
    return kExitOk;
}

// The training method and the rounds of training within the integral equation.
int integralSettings(BakeOptions& o, BakeSettings& s) {
    if (!parseTrainingMethod(o.training, s.training))
        return usage("--training " + o.training + ": expected monte-carlo or integral");
    if (o.integral.paths < 1 || o.integral.epochs < 1 || o.integral.startEpochs < 1 || o.integral.startRestarts < 0 || o.integral.startRestarts > 64 || o.integral.bounces < 1 || o.integral.bounces > 8)
        return usage("--generation-paths, --generation-epochs and --start-epochs must be positive, --start-restarts 0 to 64, --bounces 1 to 8");
    if (!o.generationLr.empty()) {
        std::vector<float> lr;
        if (!parseFloats(o.generationLr, lr) || lr.size() != 2 || !(lr[0] > 0.0f) || !(lr[1] > 0.0f))
            return usage("--generation-lr " + o.generationLr + ": expected two positive learning rates, first,last");
        o.integral.learningRate = lr[0];
        o.integral.finalLearningRate = lr[1];
    }
    if (!(o.integral.averageDecay >= 0.0f && o.integral.averageDecay < 1.0f))
        return usage("--average-decay must be in [0, 1)");
    s.integral = o.integral;
    return kExitOk;
}

// The bake's settings from the options (usage errors refused before any work), automatic values resolved.
int settingsFromOptions(BakeOptions& o, BakeSettings& s) {
    if (int code = networkSettings(o, s)) return code;
    if (int code = partitionSettings(o, s)) return code;
    if (int code = integralSettings(o, s)) return code;
    if (!parseNeeMode(o.nee, s.nee.mode)) return usage("--nee " + o.nee + ": expected power, uniform or learned");
    s.samples.points = o.points;
    s.samples.paths = o.paths;
    s.samples.extraPathsFactor = o.noisyPaths;
    s.samples.noisyRelativeError = o.noisyError;
    s.samples.maxDepth = o.maxDepth;
    s.samples.seed = o.seed;
    s.samples.minSamplesPerVoxel = o.minSamples;
    s.train.epochs = o.epochs;
    s.train.batchSize = o.batch;
    s.train.patience = o.patience;
    s.train.raceEpochs = o.raceEpochs;
    s.train.raceAll = o.raceAll;
    s.train.restarts = o.restarts;
    s.train.epochAverage = o.epochAverage;
    s.train.learningRate = o.learningRate;
    s.train.seed = o.seed;
    s.metadata = !o.noMetadata;
    s.volume.enabled = o.volumePoints > 0;
    s.volume.pointsPerCell = o.volumePoints;
    s.volume.paths = o.volumePaths;
    s.volume.glossy = o.volumeGlossy;  // like --volume-paths, nothing without --volume-points
    if (s.volume.enabled && (o.volumePaths == 0 || o.volumePaths > 4096)) return usage("--volume-paths: expected 1 to 4096");
    if (s.volume.enabled && o.volumePoints > 1000000) return usage("--volume-points: expected at most 1000000");
    if (s.volume.enabled && s.partition.budgetBytes > 0) {  // the smallest asset has a volume network too
        const uint64_t smallest = format::encodedSize(bakeTopology(s), 1, 1, 0, 1, s.volume.glossy ? 1 : 0);
        if (s.partition.budgetBytes < smallest)
            return usage("--budget " + o.budget + " with --volume-points: below the smallest asset of one network and " +
                         (s.volume.glossy ? "two of the volume (" : "one of the volume (") + std::to_string(smallest) + " bytes)");
    }
    s.train.demodulate = !o.noDemodulate;
    s.walls.enabled = !o.noWallSplits;
    s = resolvedBakeSettings(s);
    return kExitOk;
}

// Says which lights the engine draws and which the asset holds whole.
void reportMixedLighting(const Scene& scene) {
    std::string drawn;
    size_t baked = 0;
    for (const PunctualLight& l : scene.lights) {
        if (l.runtimeDirect)
            drawn += (drawn.empty() ? "" : ", ") + (!l.name.empty() ? "'" + l.name + "'"
                                                    : l.type == PunctualLight::Type::Directional ? std::string("a directional light")
                                                                                                  : std::string("a punctual light"));
        else
            ++baked;
    }
    if (!drawn.empty())
        std::fprintf(stderr, "lighting: mixed: the engine draws the direct light of %s (its shadows sharp), the asset holds "
                             "their indirect light and everything else%s; --runtime-direct none bakes it all\n",
                     drawn.c_str(), baked ? (" (" + std::to_string(baked) + " soft light(s) baked whole)").c_str() : "");
    else if (baked)
        std::fprintf(stderr, "lighting: %zu punctual light(s) baked whole, direct light included (soft, or --runtime-direct "
                             "none): the asset smears sharp direct light\n", baked);
}

// The scene, lit as the flags and the config file say (into s.lightingJson).
int loadLitScene(const BakeOptions& o, CLI::App* cmd, const std::set<std::string>& configKeys, Scene& scene, BakeSettings& s) {
    if (int code = loadSceneForCommand("bake", o.scene, o.quiet, scene, o.importLimits)) return code;
    // (No lighting was recorded before the bake: whether any lighting flag was given does not matter.)
    if (int code = applyLightingForCommand("bake", o.lighting, true, cmd->count("--environment") > 0 || configKeys.count("environment") > 0,
                                           o.quiet, scene, {}, &s.lightingJson))
        return code;
    if (!o.quiet) reportMixedLighting(scene);
    return kExitOk;
}

// Bakes, with progress on stderr, and writes the asset (its bytes into `bytes`); with a group, every process
// bakes its share and the first writes.
int bakeAndWrite(const BakeOptions& o, const Scene& scene, const BakeSettings& s, BakeResult& r, std::vector<uint8_t>& bytes,
                 double& writeSeconds, const BakeGroup* group) {
    ProgressBar sampling("sampling", !o.quiet), partition("partition", !o.quiet), training("training", !o.quiet);
    try {
        BakeProgress progress{[&](double f) { sampling.update(f); }, [&](double f) { training.update(f); }, {},
                              [&](double f) { partition.update(f); }};
        if (!o.saveGenerations.empty())
            progress.generation = [&](uint32_t g, const BakeResult& soFar) {
                writeBytesAtomically(o.saveGenerations + "-g" + std::to_string(g) + ".nrad", format::encode(soFar.asset));
            };
        r = bakeScene(scene, s, progress, group);
    } catch (const IoError& e) {  // --save-generations
        std::fprintf(stderr, "nrad bake: %s\n", e.what());
        return kExitIo;
    } catch (const std::runtime_error& e) {  // a budget below the smallest asset
        std::fprintf(stderr, "nrad bake: %s\n", e.what());
        return kExitUsage;
    }
    auto t = std::chrono::steady_clock::now();
    bytes = format::encode(r.asset);
    if (group && group->rank() != 0) return kExitOk;  // the first process writes
    try {
        writeBytesAtomically(o.output, bytes);
    } catch (const IoError& e) {
        std::fprintf(stderr, "nrad bake: %s\n", e.what());
        return kExitIo;
    }
    writeSeconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t).count();
    return kExitOk;
}

// The networks' held-out errors, summed up.
struct HeldOutSummary {
    double mean = 0.0, worst = 0.0;
    uint32_t worstVoxel = 0;
    size_t retrained = 0, fallbacks = 0;
};

HeldOutSummary heldOutSummary(const BakeResult& r) {
    HeldOutSummary h;
    for (const VoxelTrainResult& v : r.voxels) {
        h.mean += v.heldOutRelMse;
        if (v.heldOutRelMse >= h.worst) {
            h.worst = v.heldOutRelMse;
            h.worstVoxel = v.voxel;
        }
        h.retrained += v.attempts > 1 ? 1 : 0;
        h.fallbacks += v.fallback ? 1 : 0;
    }
    if (!r.voxels.empty()) h.mean /= double(r.voxels.size());
    return h;
}

// The timings of a bake run.
struct BakeTimes {
    double load = 0.0, write = 0.0;
};

void printBakeLine(const BakeOptions& o, const BakeSettings& s, const BakeResult& r, const HeldOutSummary& h, size_t bytes,
                   const BakeTimes& times) {
    for (const VoxelTrainResult& v : r.voxels)
        for (const std::string& e : v.events) std::fprintf(stderr, "voxel %u: %s\n", v.voxel, e.c_str());
    std::printf("baked %s -> %s: %zu bytes, %zu of %u %s occupied, %zu samples (%llu floor, %llu hidden, %llu dropped, %llu "
                "non-finite paths, %llu noisy with %llu extra paths, up to %ux the paths), held-out relMSE mean %.4g worst %.4g (voxel %u), %zu retrained, %zu fallback; "
                "time: load %.2f s, setup %.2f s, sampling %.2f s, partition %.2f s, training %.2f s, writing %.3f s\n",
                o.scene.c_str(), o.output.c_str(), bytes, r.voxels.size(), unsigned(r.asset.cellCount()),
                r.asset.tree.empty() ? "voxels" : "leaves", r.sampleCount,
                (unsigned long long)r.sampleStats.floorPoints, (unsigned long long)r.sampleStats.hiddenSamples,
                (unsigned long long)r.sampleStats.droppedSamples, (unsigned long long)r.sampleStats.nonFinitePaths,
                (unsigned long long)r.sampleStats.noisyPoints, (unsigned long long)r.sampleStats.extraPaths, s.samples.extraPathsFactor, h.mean, h.worst, h.worstVoxel, h.retrained,
                h.fallbacks, times.load, r.timings.setup, r.timings.sampling, r.timings.partition, r.timings.training, times.write);
}

// Networks this small smear sharp light: where the held-out error is large, says what that likely is and
// what to do about it, rather than leave two large numbers in a long line.
void warnLargeHeldOut(const Scene& scene, const BakeResult& r, const HeldOutSummary& h) {
    if (!(h.mean > kLargeHeldOutMean || h.worst > kLargeHeldOutWorst)) return;
    size_t baked = 0;
    bool sunBaked = false;
    for (const PunctualLight& l : scene.lights)
        if (!l.runtimeDirect) {
            ++baked;
            sunBaked = sunBaked || l.type == PunctualLight::Type::Directional;
        }
    const std::string cause = sunBaked ? "the sun's sharp direct light, baked into the asset"
                              : baked  ? std::to_string(baked) + " punctual light(s) whose sharp direct light is baked into the asset"
                                       : "small or bright emitters whose sharp direct light is baked into the asset";
    std::fprintf(stderr, "warning: large held-out error (relMSE mean %.3g, worst %.3g in %s %u; above %g or %g the asset "
                         "visibly smears light): likely %s. Remedies: %s a finer partition (--budget larger, or --grid)\n",
                 h.mean, h.worst, r.asset.tree.empty() ? "voxel" : "leaf", h.worstVoxel, kLargeHeldOutMean, kLargeHeldOutWorst,
                 cause.c_str(), baked ? "--runtime-direct sun|all|NAME (the engine draws their direct light, the asset keeps the rest);"
                                      : "");
}

// The rounds of training within the integral equation and the partition, a line each.
void printRoundsAndPartition(const BakeSettings& s, const BakeResult& r, size_t bytes) {
    if (!r.generations.empty()) {
        const GenerationStats& last = r.generations.back();
        std::printf("training within the integral equation: a Monte Carlo start (%zu samples, %.2f s) and %zu rounds of %zu "
                    "samples; held-out relMSE against the targets %.4g after the start, %.4g after the last round\n",
                    r.generations.front().samples, r.generations.front().samplingSeconds + r.generations.front().trainingSeconds,
                    r.generations.size() - 1, last.samples, r.generations.front().heldOutRelMse, last.heldOutRelMse);
    }
    const AdaptivePartition& ap = r.partition;
    if (s.partition.budgetBytes > 0) {
        uint32_t deepest = 0;
        for (const PartitionLeafInfo& l : ap.leaves) deepest = std::max(deepest, l.depth);
        std::printf("partition: kd-tree of %u leaves (%u with surface, depth up to %u) on a %ux%ux%u lattice, %zu nodes; "
                    "%llu of %llu budget bytes; residual %.4g of %.4g left\n",
                    ap.leafCount, ap.networks, deepest, r.asset.grid.dims[0], r.asset.grid.dims[1], r.asset.grid.dims[2],
                    ap.tree.size(), (unsigned long long)bytes, (unsigned long long)s.partition.budgetBytes, ap.residual,
                    ap.rootResidual);
    } else if (ap.leafCount > 0) {
        const uint64_t cells = uint64_t(s.grid.x) * s.grid.y * s.grid.z;
        const size_t hard = format::hardPlanes(ap.tree);
        std::printf("partition: the %ux%ux%u grid split at walls where a cell holds a lit and a dark side (%llu splits, %zu inside a "
                    "wall with no blending across: %u leaves, %u with surface, on a %ux%ux%u lattice; --no-wall-splits keeps the "
                    "cells whole)\n",
                    s.grid.x, s.grid.y, s.grid.z, (unsigned long long)(ap.leafCount - cells), hard, ap.leafCount, ap.networks,
                    r.asset.grid.dims[0], r.asset.grid.dims[1], r.asset.grid.dims[2]);
    }
}

// The volume's networks (--volume-points), a line.
void printVolume(const BakeResult& r) {
    if (r.volumeStats.tried == 0) return;
    auto heldOut = [](const std::vector<VoxelTrainResult>& networks, double& mean, double& worst) {
        mean = worst = 0.0;
        for (const VoxelTrainResult& v : networks) {
            mean += v.heldOutRelMse / double(networks.size());
            worst = std::max(worst, v.heldOutRelMse);
        }
    };
    double mean, worst;
    heldOut(r.volume, mean, worst);
    std::printf("volume: %zu networks of the light for receivers not in the bake, from %llu points tried in the cells (%llu "
                "inside closed solids, dropped; %llu noisy with %llu extra paths), held-out relMSE mean %.4g worst %.4g",
                r.volume.size(), (unsigned long long)r.volumeStats.tried, (unsigned long long)r.volumeStats.inside,
                (unsigned long long)r.volumeStats.noisyPoints, (unsigned long long)r.volumeStats.extraPaths, mean, worst);
    if (!r.glossy.empty()) {
        heldOut(r.glossy, mean, worst);
        std::printf("; glossy response (roughness %.1f): %zu networks, held-out relMSE mean %.4g worst %.4g", double(eval::kGlossyRoughness),
                    r.glossy.size(), mean, worst);
    }
    std::printf("; %.2f s\n", r.timings.volume);
}

// --stats: the kd-tree and its leaves.
nlohmann::json partitionStats(const BakeSettings& s, const BakeResult& r) {
    const AdaptivePartition& ap = r.partition;
    nlohmann::json leaves = nlohmann::json::array();
    for (size_t i = 0; i < ap.leaves.size(); ++i) {
        const PartitionLeafInfo& l = ap.leaves[i];
        leaves.push_back({{"leaf", i}, {"depth", l.depth}, {"lo", {l.box.lo[0], l.box.lo[1], l.box.lo[2]}},
                          {"hi", {l.box.hi[0], l.box.hi[1], l.box.hi[2]}}, {"samples", l.samples},
                          {"residual", l.residual}});
    }
    return {{"kind", "kd-tree"},
            {"budget_bytes", s.partition.budgetBytes},
            {"lattice", {r.asset.grid.dims[0], r.asset.grid.dims[1], r.asset.grid.dims[2]}},
            {"nodes", ap.tree.size()},
            {"leaves", ap.leafCount},
            {"networks", ap.networks},
            {"splits_skipped_for_budget", ap.splitsSkippedForBudget},
            {"root_residual", ap.rootResidual},
            {"residual", ap.residual},
            {"cells", leaves}};
}

// --stats: the training method and its rounds, with the time elapsed at the end of each.
nlohmann::json trainingStats(const BakeSettings& s, const BakeResult& r, const BakeTimes& times) {
    nlohmann::json rounds = nlohmann::json::array();
    double elapsed = times.load + r.timings.setup + r.timings.partition;
    for (const GenerationStats& g : r.generations) {
        elapsed += g.samplingSeconds + g.trainingSeconds;
        rounds.push_back({{"generation", g.generation}, {"samples", g.samples}, {"rays", g.rays},
                          {"sampling_seconds", g.samplingSeconds}, {"training_seconds", g.trainingSeconds},
                          {"elapsed_seconds", elapsed}, {"learning_rate", g.learningRate},
                          {"held_out_relmse_against_targets", g.heldOutRelMse}});
    }
    return {{"method", trainingMethodName(s.training)}, {"generations", rounds}};
}

// --stats: every network's training.
nlohmann::json voxelStats(const BakeResult& r) {
    nlohmann::json voxels = nlohmann::json::array();
    for (const VoxelTrainResult& v : r.voxels) {
        nlohmann::json curve = nlohmann::json::array();
        for (const TrainCurvePoint& c : v.curve) curve.push_back({c.epoch, c.seconds, c.heldOutRelMse});
        voxels.push_back({{"voxel", v.voxel}, {"train_samples", v.trainCount}, {"held_out_samples", v.heldOutCount},
                          {"held_out_relmse", v.heldOutRelMse}, {"train_relmse", v.trainRelMse}, {"scale", v.scale},
                          {"epochs", v.epochs}, {"attempts", v.attempts}, {"fallback", v.fallback},
                          {"weight_decay", v.weightDecay},
                          {"events", v.events}, {"seconds", v.seconds},
                          {"curve_epoch_seconds_relmse", curve}});
    }
    return voxels;
}

int writeBakeStats(const BakeOptions& o, const BakeSettings& s, const Scene& scene, const BakeResult& r, const HeldOutSummary& h,
                   size_t bytes, const BakeTimes& times) {
    nlohmann::json j;
    if (s.partition.budgetBytes > 0) j["partition"] = partitionStats(s, r);
    j["training"] = trainingStats(s, r, times);
    j["scene"] = o.scene;
    j["asset"] = o.output;
    j["asset_bytes"] = bytes;
    j["grid"] = {s.grid.x, s.grid.y, s.grid.z};
    j["occupied_voxels"] = r.voxels.size();
    j["samples"] = r.sampleCount;
    j["floor_samples"] = r.sampleStats.floorPoints;
    j["dropped_samples"] = r.sampleStats.droppedSamples;
    j["hidden_samples"] = r.sampleStats.hiddenSamples;
    j["non_finite_paths"] = r.sampleStats.nonFinitePaths;
    j["noisy_samples"] = r.sampleStats.noisyPoints;
    j["noisy_extra_paths"] = r.sampleStats.extraPaths;
    j["nee"] = {{"mode", neeModeName(s.nee.mode)},
                {"warmup_paths", r.sampleStats.neeWarmupPaths},
                {"training_steps", r.sampleStats.neeTrainingSteps},
                {"warmup_seconds", r.sampleStats.neeWarmupSeconds}};
    j["rays"] = r.sampleStats.rays.total();
    j["surface_area"] = r.surfaceArea;
    j["held_out_relmse"] = {{"mean", h.mean}, {"worst", h.worst}, {"worst_voxel", h.worstVoxel}};
    j["seconds"] = {{"load", times.load}, {"setup", r.timings.setup}, {"sampling", r.timings.sampling},
                    {"partition", r.timings.partition}, {"training", r.timings.training}, {"writing", times.write}};
    j["settings"] = nlohmann::json::parse(assetMetadata(scene, s, r))["bake"];
    BakeOptions given = o;
    j["config"] = bakeSettingsTable(given).json();  // a --config file that repeats this bake
    j["voxels"] = voxelStats(r);
    if (s.volume.enabled) {
        auto networks = [](const std::vector<VoxelTrainResult>& list) {
            nlohmann::json cells = nlohmann::json::array();
            for (const VoxelTrainResult& v : list)
                cells.push_back({{"cell", v.voxel}, {"samples", v.trainCount + v.heldOutCount}, {"held_out_relmse", v.heldOutRelMse},
                                 {"train_relmse", v.trainRelMse}, {"scale", v.scale}});
            return cells;
        };
        j["volume"] = {{"points_tried", r.volumeStats.tried}, {"points_inside_solids", r.volumeStats.inside},
                       {"noisy_points", r.volumeStats.noisyPoints + r.glossyStats.noisyPoints},
                       {"extra_paths", r.volumeStats.extraPaths + r.glossyStats.extraPaths},
                       {"rays", r.volumeStats.rays + r.glossyStats.rays}, {"seconds", r.timings.volume}, {"networks", networks(r.volume)}};
        if (s.volume.glossy) j["volume"]["glossy_networks"] = networks(r.glossy);
    }
    try {
        writeTextAtomically(o.stats, j.dump(1) + "\n");
    } catch (const IoError& e) {
        std::fprintf(stderr, "nrad bake: %s\n", e.what());
        return kExitIo;
    }
    return kExitOk;
}

// The processes of an MPI launch: exit codes agreed (the first process's), so that none waits for another that left.
int agreed(const BakeGroup* group, int code) {
    if (!group || group->size() <= 1) return code;
    ByteWriter w;
    w.put(int32_t(code));
    const std::vector<std::vector<uint8_t>> all = group->allGather(w.bytes);
    ByteReader first(all.front());
    return first.get<int32_t>();
}

// The settings of --preset NAME, as --config keys; null for a name that is none. "production" is the defaults;
// "preview" trades error for time: paths cut at six segments, no extra paths for noisy targets, one start a network
// (the Cornell box 3.7 s against 7 s, at 2.2x the relMSE; docs/performance.md, "Bake time against error").
nlohmann::json presetSettings(const std::string& name) {
    if (name == "production") return nlohmann::json::object();
    if (name == "preview") return {{"max_depth", 6}, {"noisy_paths", 1}, {"restarts", 1}};
    return nullptr;
}

// The settings from --preset, then --config (its keys into configKeys; they win over the preset's) and the flags
// (which win over both); with --dump-config they are printed (if `print`) and `dumped` is set: the command ends
// there.
int readSettings(BakeOptions& o, CLI::App* cmd, bool print, std::set<std::string>& configKeys, BakeSettings& s, bool& dumped) {
    if (!o.preset.empty()) {
        const nlohmann::json preset = presetSettings(o.preset);
        if (preset.is_null()) return usage("--preset " + o.preset + ": expected preview or production");
        bakeSettingsTable(o).readConfig(preset, cmd);
    }
    if (!o.config.empty())
        if (int code = readConfig(o, cmd, configKeys)) return code;
    if (int code = settingsFromOptions(o, s)) return code;
    dumped = o.dumpConfig;
    if (dumped && print) std::printf("%s\n", bakeSettingsTable(o).json().dump(2).c_str());
    return kExitOk;
}

int runBake(BakeOptions o, CLI::App* cmd, const BakeGroup* group) {
    const bool first = !group || group->rank() == 0;  // the process that prints, checks the outputs and writes
    if (!first) o.quiet = true;
    std::set<std::string> configKeys;
    BakeSettings s;
    bool dumped = false;
    if (int code = readSettings(o, cmd, first, configKeys, s, dumped); code || dumped) return code;
    {
        std::vector<std::string> outputs = {o.output};
        if (!o.stats.empty()) outputs.push_back(o.stats);
        if (!o.saveGenerations.empty()) outputs.push_back(o.saveGenerations + "-g0.nrad");
        if (int code = agreed(group, first ? checkOutputsForCommand("bake", outputs) : kExitOk)) return code;
    }
    if (!first) o.saveGenerations.clear();
    ThreadScope threads(o.threads);
    BakeTimes times;
    auto t0 = std::chrono::steady_clock::now();
    Scene scene;
    if (int code = loadLitScene(o, cmd, configKeys, scene, s)) return code;
    times.load = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    BakeResult r;
    std::vector<uint8_t> bytes;
    if (int code = bakeAndWrite(o, scene, s, r, bytes, times.write, group)) return code;
    if (!first) return kExitOk;
    const HeldOutSummary h = heldOutSummary(r);
    printBakeLine(o, s, r, h, bytes.size(), times);
    if (group && group->size() > 1)
        std::printf("processes: %d (MPI); the first decided the points (as every process does) in %.2f s, waited for the others "
                    "and exchanged with them for %.2f s\n",
                    group->size(), r.sampleStats.planSeconds, group->exchangeSeconds());
    warnLargeHeldOut(scene, r, h);
    printRoundsAndPartition(s, r, bytes.size());
    printVolume(r);
    if (!o.stats.empty()) return writeBakeStats(o, s, scene, r, h, bytes.size(), times);
    return kExitOk;
}

// The stage-1 parts in folder `dir` (the files that are parts of traced samples; others are passed over), checked to
// be this bake's N shards, each once; in shard order.
std::vector<std::string> tracedParts(const std::string& dir, const ShardPartHeader& expected) {
    std::vector<std::string> paths;
    std::vector<ShardPartHeader> headers;
    std::error_code ec;
    std::vector<std::string> files;
    std::filesystem::directory_iterator it(dir, ec), end;
    for (; !ec && it != end; it.increment(ec))
        if (it->is_regular_file(ec)) files.push_back(it->path().string());
    if (ec) throw IoError(dir + ": cannot be read: " + ec.message());
    std::sort(files.begin(), files.end());
    for (const std::string& f : files) {
        char magic[8] = {};
        std::ifstream(f, std::ios::binary).read(magic, sizeof magic);
        if (std::string(magic, sizeof magic) != "NRADPART") continue;  // not a part
        if (readShardPartHeader(f, false).kind != ShardPartKind::TracedSamples) continue;  // the networks' (maybe being written)
        paths.push_back(f);
        headers.push_back(readShardPartHeader(f));
    }
    if (paths.empty()) throw ShardPartError(dir + ": holds no parts of traced samples (bake --shard K/N --trace-only first)");
    checkShardSet(paths, headers, &expected);
    std::vector<std::string> ordered(paths.size());
    for (size_t i = 0; i < paths.size(); ++i) ordered[headers[i].shard.index] = paths[i];
    return ordered;
}

// A shard of a bake (bake_shard.h): --trace-only, its share of the traced points (stage 1); else its share of the
// networks (stage 2), from the stage-1 parts in --traced DIR or tracing every point itself. Writes a part.
int runShardBake(BakeOptions o, CLI::App* cmd) {
    ShardId shard;
    if (!parseShardId(o.shard, shard)) {
        std::fprintf(stderr, "nrad bake: --shard %s: not K/N with 0 <= K < N <= %u (shard K of N, counted from 0)\n", o.shard.c_str(),
                     kMaxShards);
        return kExitUsage;
    }
    if (o.traceOnly && !o.traced.empty()) {
        std::fprintf(stderr, "nrad bake: --trace-only (stage 1) and --traced (stage 2) are two runs of a shard, not one\n");
        return kExitUsage;
    }
    if (!o.stats.empty()) {
        std::fprintf(stderr, "nrad bake: --stats describes a whole bake; a shard holds a part of one (merge the parts, then "
                             "`nrad info` the asset)\n");
        return kExitUsage;
    }
    std::set<std::string> configKeys;
    BakeSettings s;
    bool dumped = false;
    if (int code = readSettings(o, cmd, true, configKeys, s, dumped); code || dumped) return code;
    if (s.training == TrainingMethod::Integral) {
        std::fprintf(stderr, "nrad bake: --shard: %s\n", kShardsNotIntegral);
        return kExitUsage;
    }
    if (int code = checkOutputsForCommand("bake", {o.output})) return code;
    ThreadScope threads(o.threads);
    auto t0 = std::chrono::steady_clock::now();
    Scene scene;
    if (int code = loadLitScene(o, cmd, configKeys, scene, s)) return code;
    const double load = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    ShardPartHeader header;
    header.shard = shard;
    header.sceneHash = sceneHash(scene);
    // Every setting as a config file would repeat it (shards of one bake are run with the same ones), and what
    // the parts' bytes depend on in the build: a traced sample's layout and the byte order.
    const std::string settingsText = bakeSettingsTable(o).json().dump();
    header.settingsHash = kFnvOffsetBasis;
    fnv1a(header.settingsHash, settingsText.data(), settingsText.size());
    const uint32_t layout[2] = {uint32_t(sizeof(TrainingSample)), 0x01020304u};
    fnv1a(header.settingsHash, layout, sizeof layout);

    ProgressBar sampling("sampling", !o.quiet), partition("partition", !o.quiet), training("training", !o.quiet);
    const BakeProgress progress{[&](double f) { sampling.update(f); }, [&](double f) { training.update(f); }, {},
                                [&](double f) { partition.update(f); }};
    const std::string name = "shard " + std::to_string(shard.index) + " of " + std::to_string(shard.count);
    try {
        if (o.traceOnly) {
            header.kind = ShardPartKind::TracedSamples;
            BakeResult r;
            const std::vector<uint8_t> payload = tracedSamplesPayload(traceShard(scene, s, shard, progress, &r));
            writeShardPart(o.output, header, payload);
            std::printf("traced %s of %s -> %s: %zu bytes, %llu rays; time: load %.2f s, setup %.2f s, sampling %.2f s (deciding the "
                        "points %.2f s, as every shard does)\n",
                        name.c_str(), o.scene.c_str(), o.output.c_str(), payload.size() + kPartHeaderSize,
                        (unsigned long long)r.sampleStats.rays.total(), load, r.timings.setup, r.timings.sampling,
                        r.sampleStats.planSeconds);
            return kExitOk;
        }
        header.kind = ShardPartKind::Networks;
        std::vector<std::string> parts;
        std::unique_ptr<ShardGroup> group;
        try {
            if (!o.traced.empty()) {
                ShardPartHeader expected = header;
                expected.kind = ShardPartKind::TracedSamples;
                parts = tracedParts(o.traced, expected);
            }
            group = std::make_unique<ShardGroup>(shard, parts);
        } catch (const IoError& e) {  // the parts cannot be read: input
            throw ShardPartError(e.what());
        }
        std::vector<uint32_t> trained;
        const BakeResult r = bakeShard(scene, s, *group, progress, trained);
        const std::vector<uint8_t> payload = networksPayload(trained, format::encode(r.asset));
        writeShardPart(o.output, header, payload);
        std::printf("baked %s of %s -> %s: %zu of %zu networks trained here, %zu samples (%s); time: load %.2f s, setup %.2f s, "
                    "sampling %.2f s, partition %.2f s, training %.2f s; merge the %u parts with `nrad merge PARTS -o ASSET`\n",
                    name.c_str(), o.scene.c_str(), o.output.c_str(), trained.size(), r.voxels.size(), r.sampleCount,
                    parts.empty() ? "traced here" : "read from the traced parts", load, r.timings.setup, r.timings.sampling,
                    r.timings.partition, r.timings.training, shard.count);
    } catch (const ShardPartError& e) {
        std::fprintf(stderr, "nrad bake: %s\n", e.what());
        return kExitBadInput;
    } catch (const IoError& e) {
        std::fprintf(stderr, "nrad bake: %s\n", e.what());
        return kExitIo;
    } catch (const std::runtime_error& e) {  // a budget below the smallest asset
        std::fprintf(stderr, "nrad bake: %s\n", e.what());
        return kExitUsage;
    }
    return kExitOk;
}

// A bake in this process, or, launched by mpirun, on every process of the launch.
int runBakeCommand(const BakeOptions& o, CLI::App* cmd) {
    if (o.shard.empty() && (o.traceOnly || !o.traced.empty())) {
        std::fprintf(stderr, "nrad bake: %s needs --shard K/N\n", o.traceOnly ? "--trace-only" : "--traced");
        return kExitUsage;
    }
    if (!o.shard.empty()) {
        if (launchedByMpi()) {
            std::fprintf(stderr, "nrad bake: --shard under an MPI launcher: a shard is one process of a farm's array job; "
                                 "mpirun bakes the whole scene together (leave out --shard)\n");
            return kExitUsage;
        }
        return runShardBake(o, cmd);
    }
    if (!launchedByMpi()) return runBake(o, cmd, nullptr);
#if defined(NRAD_HAVE_MPI)
    try {
        MpiGroup group;
        BakeOptions mine = o;
        // --threads 0 (all): a process bound to cores takes them; unbound, the machine's cores are shared by its
        // processes (two processes on two cores would otherwise run four threads).
        if (mine.threads == 0) {
            const int cores = coresAvailable(), hardware = int(std::thread::hardware_concurrency());
            mine.threads = cores < hardware ? cores : std::max(1, cores / group.processesOnThisMachine());
        }
        return runBake(mine, cmd, &group);
    } catch (const std::runtime_error& e) {
        std::fprintf(stderr, "nrad bake: MPI: %s\n", e.what());
        return kExitIo;
    }
#else
    std::fprintf(stderr, "nrad bake: started by an MPI launcher, but this nrad was built without MPI (install libopenmpi-dev and "
                         "rebuild); bake with one process instead\n");
    return kExitUsage;
#endif
}

}  // namespace

std::function<int()> addBakeCommand(CLI::App& app) {
    auto o = std::make_shared<BakeOptions>();
    CLI::App* cmd = app.add_subcommand("bake", "Bake a glTF scene into a neural radiance asset (.nrad)");
    cmd->add_option("scene", o->scene, "glTF 2.0 scene (.gltf or .glb)")->required();
    cmd->add_option("-o,--output", o->output, "Output asset (.nrad)")->required();
    bakeSettingsTable(*o).addOptions(cmd);
    cmd->add_option("--save-generations", o->saveGenerations,
                    "Integral training: also write the asset after every round as PREFIX-gN.nrad (N = 0 is the Monte Carlo start)");
    cmd->add_option("--threads", o->threads, "Worker threads; 0 = all (does not change the asset)")->check(CLI::Range(0, 4096));
    cmd->add_option("--config", o->config,
                    "JSON file of bake settings (keys as the flags, with underscores, \"--no-X\" as \"X\": false); flags win");
    cmd->add_option("--preset", o->preset,
                    "preview (paths cut at 6 segments, no extra paths for noisy targets, one start a network: about half the "
                    "bake time at about twice the error) or production (the defaults); --config's keys and the flags win");
    cmd->add_flag("--dump-config", o->dumpConfig,
                  "Print every setting as --config reads it (the file's and the flags' values, the rest at their defaults) and "
                  "exit without baking");
    cmd->add_option("--stats", o->stats, "Write machine-readable statistics (JSON) here");
    cmd->add_option("--shard", o->shard,
                    "K/N: bake shard K of N (from 0) of a farm's array job and write a part (`nrad merge` makes the asset); "
                    "Monte Carlo training only");
    cmd->add_flag("--trace-only", o->traceOnly,
                  "With --shard: only trace this shard's share of the points and write them as a part (stage 1 of two)");
    cmd->add_option("--traced", o->traced,
                    "With --shard: the folder of every shard's --trace-only part (stage 2: train this shard's networks on "
                    "them); without it a shard traces every point itself");
    cmd->add_flag("-q,--quiet", o->quiet, "No progress on stderr");
    return [o, cmd]() { return runBakeCommand(*o, cmd); };
}

}  // namespace nrad
