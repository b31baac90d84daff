// Validation: the scene path traced (the reference) against the same view rendered through a baked asset
// and through the SH-probe baseline, with error against run time measured in the same run.
#pragma once

#include <functional>
#include <optional>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>
#include <nrad/eval.h>
#include <nrad/format.h>
#include <nrad/nrad.h>

#include "baker/bake/training_samples.h"
#include "baker/render/accel.h"
#include "baker/render/image_io.h"
#include "baker/render/path_tracer.h"
#include "baker/scene/scene.h"
#include "baker/validate/metrics.h"
#include "baker/validate/sh_irradiance.h"
#include "baker/validate/sh_probes.h"

namespace nrad {

// The SH baseline's training budget: at most max(kBaselineMinPoints, kBaselinePointsPerProbe x probes) of the
// bake's points (the first of its sequence), and at most max(kBaselineMinPaths, kBaselinePathsPerProbe x probes)
// paths in all, fewer paths per point first (re-tracing every sample of a large bake took nearly all of its
// validation). Each is the smallest budget whose probes are as good as with every sample of the bake (image
// relMSE), measured on the Cornell box and on zdm2 under a 1 MB budget: docs/usage.md ("Baseline") has the sweep
// and the times.
constexpr uint32_t kBaselinePointsPerProbe = 25;
constexpr uint32_t kBaselineMinPoints = 40000;
constexpr uint32_t kBaselinePathsPerProbe = 200;
constexpr uint64_t kBaselineMinPaths = uint64_t(1) << 21;

struct ValidateSettings {
    int width = 512, height = 0;  // height 0: from the width and the camera's aspect ratio
    Camera camera;
    int referenceSpp = 512;  // the paper's reference
    int maxDepth = 0;  // path length of the reference and the convergence curve (segments; 0 = unbounded: the truth)
    int neuralSpp = 4;  // the paper's: primary visibility anti-aliasing for neural and baseline renders
    int curveMaxSpp = 64;  // the path tracer's convergence curve: 1, 2, 4, ... up to this
    uint32_t seed = 0;  // the reference's; the curve uses seed + 1 (independent of the reference)
    std::string cacheDir;  // the reference's and the SH baseline's cache; empty: no cache
    std::string referenceImage;  // use this EXR as the reference instead of rendering one
    bool baseline = true;  // fit and render the SH-probe baseline
    // The baseline's training budget (kBaselinePointsPerProbe says why): at most max(baselineMinPoints,
    // baselinePointsPerProbe x probes) of the bake's points, the first of its sequence (0 per probe: all), and
    // at most max(baselineMinPaths, baselinePathsPerProbe x probes) paths in all, fewer paths per point first
    // (at least 1; 0 per probe: the bake's paths per point).
    uint32_t baselinePointsPerProbe = kBaselinePointsPerProbe;
    uint32_t baselineMinPoints = kBaselineMinPoints;
    uint32_t baselinePathsPerProbe = kBaselinePathsPerProbe;
    uint64_t baselineMinPaths = kBaselineMinPaths;
    float exposure = 0.0f;  // for PSNR and PNGs
};

struct CurvePoint {
    int spp = 0;
    double seconds = 0.0;  // wall time of that render alone
    ImageMetrics metrics;
};

// A first-hit render (neural or baseline) and its score.
struct MethodResult {
    std::string name;
    Image image;
    ImageMetrics metrics;
    double seconds = 0.0;  // wall time of the render
    double visibilitySeconds = 0.0;  // wall time share of primary visibility (thread-time proportion)
    double evaluationSeconds = 0.0;  // wall time share of radiance evaluation
    uint64_t evaluations = 0, outsideGrid = 0, emptyVoxel = 0;
    size_t bytes = 0;  // the representation's size: network weights, or probe coefficients as fp16
    std::vector<DecadeError> byDecade;
    ErrorDistribution distribution;
    std::vector<RegionError> byRegion;  // kRegionNames order
    std::vector<RegionError> byMaterial;  // the scene's materials in order, by the material each pixel's centre sees
    // What the eye sees (metrics.h): over the pixels whose centre sees a surface that does not emit. relMSE
    // there (the background, often most of an object scene's image, no longer dilutes it), the block figure
    // (blocks of width / 16 pixels) and the steps across the partition's cells.
    RegionError surfaces;
    BlockFigure blocks;
    StepFigure steps;
    // The path tracer's time to reach this image's relMSE on the convergence curve (log-log interpolation;
    // extrapolated with relMSE ~ 1/time outside it) and that time over this render's times.
    double equalErrorSeconds = 0.0;
    bool equalErrorExtrapolated = false;
    double speedupOverEvaluation = 0.0;  // equalErrorSeconds / evaluationSeconds
    double speedupOverRender = 0.0;  // equalErrorSeconds / seconds
};

// Pixel regions of the validation image, by the surface each pixel's centre sees: an emitter, a voxel border
// (a pixel whose 3 x 3 neighbourhood sees points of more than one voxel), or the rest (background included).
constexpr int kRegionCount = 3;
constexpr const char* kRegionNames[kRegionCount] = {"emitters", "voxel borders", "rest"};

// Seams: on surface points within 2% of a voxel size of a face shared by two occupied voxels, the asset's
// radiance just on either side of the face (the point projected onto it, moved 1e-4 of a voxel each way).
struct SeamFigure {
    size_t points = 0;
    // mean over points and channels of (La - Lb)^2 / (((La + Lb) / 2)^2 + 0.01): the relMSE of one side
    // against the other, comparable to the networks' held-out relMSE.
    double relMse = 0.0;
    double meanRelativeJump = 0.0;  // mean of |La - Lb| / ((La + Lb) / 2 + 0.01)
    // Networks evaluated per surface point the view sees (eval::supports after keepOccupied; 1 without
    // blending), and the share of those points in some blending band.
    double evaluationsPerPoint = 0.0;
    double blendedShare = 0.0;
};

// What the centre of each pixel of a width x height view sees (row-major): the first hit's voxel in the
// asset's grid (-1: none), whether it emits, its point, shading normal and direction towards the camera.
struct FirstHits {
    int width = 0, height = 0;
    std::vector<int64_t> voxel;
    std::vector<int> material;  // index into Scene::materials, -1 where the pixel's centre sees no surface
    std::vector<int> inserted;  // Scene::insertedObject of the surface the pixel's centre sees, -1 for the bake's or none
    std::vector<uint8_t> emitter;
    std::vector<glm::vec3> points, normals, directions;
};
// voxel: the cell (voxel or tree leaf) of the asset's partition holding each pixel's first hit, -1 if none.
FirstHits firstHits(const Scene& scene, const Accel& accel, const Camera& camera, int width, int height, const eval::Partition& partition);
// The kRegionNames region of every pixel.
std::vector<int> pixelRegions(const FirstHits& hits);
// The seam figure of `asset` on the surface points the view sees.
SeamFigure seamFigure(const FirstHits& hits, const eval::Partition& partition, NradAsset asset);
// The partition of the asset file at `path` (its grid, or its kd-tree), as the runtime locates with it.
eval::Partition assetPartition(const std::string& path);

// An object placed after the bake (--insert; issue 42), or all of them together: its interior pixels (whose
// centre and 8 neighbours' centres see it), and there the relMSE and mean luminance (over the reference's) of the
// neural image (the asset's volume query) and of the baseline's (L2 SH irradiance probes of the volume's bytes).
// The floor under both: the exact volume quantity, D(x, n) path traced in the scene without the inserted objects
// at every other pixel's centre in both directions, shaded alike (eval::shadeVolume): what no representation of
// the light in the volume can beat, since the reference also holds what the objects do to their surroundings
// (the shadow a sphere casts on the floor under it darkens the light its underside receives).
struct InsertedFigure {
    std::string name;
    size_t pixels = 0;
    double neuralRelMse = 0.0, baselineRelMse = 0.0, exactRelMse = 0.0;
    double neuralMeanRatio = 0.0, baselineMeanRatio = 0.0, exactMeanRatio = 0.0;
    size_t exactPixels = 0;
    // Against the exact volume light instead of the reference, on its pixels: what the representation alone loses.
    double neuralVsExact = 0.0, baselineVsExact = 0.0;
    // The baseline's relMSE against the reference on the exact light's pixels over the exact light's own: how far
    // below the probes a perfect query of the volume would read (the objects' effect on the light they receive, their
    // shadows and interreflections, is in the reference and in no query of the light without them); 0 without a
    // baseline.
    double bestRatio = 0.0;
    double baselineAtExact = 0.0;  // the baseline's relMSE against the reference on the exact light's pixels (0 without)
};

struct ValidationResult {
    std::string scenePath, assetPath;
    std::string environment;  // Environment::describe() of the lighting validated under
    int width = 0, height = 0;
    Image reference;
    std::string referenceSource;  // "rendered", "cache", or the given file
    std::string referenceCacheFile;
    double referenceSeconds = 0.0;  // 0 when cached or given
    ValidateSettings settings;
    std::vector<CurvePoint> curve;
    MethodResult neural;
    std::optional<MethodResult> baseline;
    // The relMSE the reference's own Monte Carlo noise adds to every figure measured against it (each image
    // here is smooth or independent of it): referenceNoise(curve, spp); < 0 when unknown (a given reference).
    double referenceNoise = -1.0;
    // The rms relative error of the reference's own block means in the neural image's block figure (its
    // floor: an exact image would read about this against the reference): referenceBlockNoise of the
    // curve's last image's block figure; < 0 when unknown (a given reference, or no blocks).
    double referenceBlockNoise = -1.0;
    ShFitStats baselineFit;
    glm::uvec3 baselineProbes{0};
    size_t baselineTrainingSamples = 0;
    uint64_t baselineTrainingPaths = 0;  // the paths traced for its samples' targets
    std::string baselineSamplesNote;  // where the baseline's training settings came from
    double baselineSeconds = 0.0;  // sampling + fit, or reading the cache
    std::string baselineSource;  // "fitted" or "cache"
    std::string baselineCacheFile;  // empty: no cache
    double baselineFittedSeconds = 0.0;  // sampling + fit when the probes were fitted (from the cache: then)
    nlohmann::json assetMetadata;  // parsed META, or null
    // Truncated light transport, said every time (issue 38): a reference or a bake whose paths were cut at a
    // length lacks the light of longer paths, which interiors are made of.
    std::vector<std::string> biasNotes;
    std::vector<int> regionOfPixel;  // kRegionNames index of each pixel
    std::vector<int> materialOfPixel;  // FirstHits::material
    std::vector<int64_t> cellOfPixel;  // FirstHits::voxel
    std::vector<uint8_t> surfaceOfPixel;  // 1 where the pixel's centre sees a surface that does not emit
    std::vector<std::string> materialNames;  // the scene's, in order ("material N" where unnamed)
    SeamFigure seams;
    // Inserted objects: one figure per object, then (with more than one) all together; the baseline's figures only
    // with the baseline. How the asset shaded them: its volume query, or (an asset without one) its surfaces'.
    std::vector<InsertedFigure> inserted;
    bool insertedThroughVolume = false;
    bool insertedThroughGlossy = false;  // ... and its glossy response
    size_t volumeBytes = 0;  // the asset's volume networks' weights (its glossy response's too)
    glm::uvec3 irradianceProbes{0};  // the baseline's irradiance probes (inserted objects only)
    ShIrradianceStats irradianceFit;
    uint32_t exactPaths = 0;  // per pixel, for InsertedFigure's exact volume quantity
};

// What of an imported scene a reference render depends on, hashed: the whole mesh (positions, normals, UVs,
// colours, tangents, triangles, material ids), every material field but the name, the textures (texels,
// decoding, wrap modes), the lights and the active environment. Not the lights' runtimeDirect (the reference
// draws every light whole: mixed lighting changes what an asset holds, not the image it is compared with)
// nor names.
uint64_t referenceSceneHash(const Scene& scene);
// Key of a reference render: referenceSceneHash, the camera, the image size, spp, path length and seed, and
// the renderer's version; nothing else (not the asset, its lighting split, the neural spp, the curve or the
// exposure). 16 hex digits.
std::string referenceKey(const Scene& scene, const ValidateSettings& s, int width, int height);

// The SH baseline's probes depend on neither the view nor the asset's weights: on the scene as baked with which
// of its lights the engine draws (their direct light is left out of the samples), the samples' settings after the
// budget, the sampling grid, the probes' box and lattice, whether they are demodulated, and the fit. Their cache
// file in `cacheDir` is named by this key (16 hex digits), so that validating an asset again (another view, spp
// or exposure) fits them once.
struct BaselineKeyInputs {
    SampleSettings samples;
    glm::uvec3 samplingDims{0};
    glm::vec3 lower{0.0f}, upper{0.0f};
    glm::uvec3 probes{0};
    bool demodulated = false;
};
std::string baselineKey(const Scene& baked, const BaselineKeyInputs& in);

// Runs the whole validation. `log` receives one line per step (may be empty). Throws std::runtime_error
// (bad reference file, evaluation failure) and IoError (cache write).
ValidationResult runValidation(const Scene& scene, const std::string& scenePath, NradAsset asset, const std::string& assetPath,
                               const ValidateSettings& settings, const std::function<void(const std::string&)>& log = {});

// The scene's materials some pixel sees, largest share of the neural image's relMSE first (ties in material
// order): the order the summary and the HTML report list them in.
std::vector<size_t> materialsByNeuralShare(const ValidationResult& r);

// The relMSE a reference of `referenceSpp` paths per pixel adds through its own noise, from the convergence
// curve's last point: against the reference, an independent N-spp render of the same estimator measures
// c / N + c / referenceSpp (its noise and the reference's; relMSE's denominator taken as fixed), so the
// reference's share is relMSE(N) N / (N + referenceSpp). An estimate: the curve's highest spp is the most
// nearly in that 1 / spp regime. 0 for an empty curve.
double referenceNoise(const std::vector<CurvePoint>& curve, int referenceSpp);
// The same split for the block figure's rms, whose squares add as relMSEs do: an independent render of
// `spp` whose blocks read `rms` against a reference of `referenceSpp` gives the reference's own share,
// rms x sqrt(spp / (spp + referenceSpp)).
double referenceBlockNoise(double rms, int spp, int referenceSpp);

// The equal-error time on a convergence curve (see MethodResult); `extrapolated` says whether the value
// lies outside the curve.
double equalErrorTime(const std::vector<CurvePoint>& curve, double relMse, bool& extrapolated);

}  // namespace nrad
