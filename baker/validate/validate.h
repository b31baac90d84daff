// Validation: the scene path traced (the reference) against the same view rendered through a baked asset
// and through the SH-probe baseline, with error against run time measured in the same run.
#pragma once

#include <functional>
#include <optional>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>
#include <nrad/nrad.h>

#include "baker/render/image_io.h"
#include "baker/render/path_tracer.h"
#include "baker/scene/scene.h"
#include "baker/validate/metrics.h"
#include "baker/validate/sh_probes.h"

namespace nrad {

struct ValidateSettings {
    int width = 512, height = 0;  // height 0: from the width and the camera's aspect ratio
    Camera camera;
    int referenceSpp = 512;  // the paper's reference
    int maxDepth = 6;  // path length of the reference and the convergence curve (segments; 0 = unbounded)
    int neuralSpp = 4;  // the paper's: primary visibility anti-aliasing for neural and baseline renders
    int curveMaxSpp = 64;  // the path tracer's convergence curve: 1, 2, 4, ... up to this
    uint32_t seed = 0;  // the reference's; the curve uses seed + 1 (independent of the reference)
    std::string cacheDir;  // reference cache; empty: no cache
    std::string referenceImage;  // use this EXR as the reference instead of rendering one
    bool baseline = true;  // fit and render the SH-probe baseline
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
    // The path tracer's time to reach this image's relMSE on the convergence curve (log-log interpolation;
    // extrapolated with relMSE ~ 1/time outside it) and that time over this render's times.
    double equalErrorSeconds = 0.0;
    bool equalErrorExtrapolated = false;
    double speedupOverEvaluation = 0.0;  // equalErrorSeconds / evaluationSeconds
    double speedupOverRender = 0.0;  // equalErrorSeconds / seconds
};

struct ValidationResult {
    std::string scenePath, assetPath;
    int width = 0, height = 0;
    Image reference;
    std::string referenceSource;  // "rendered", "cache", or the given file
    std::string referenceCacheFile;
    double referenceSeconds = 0.0;  // 0 when cached or given
    ValidateSettings settings;
    std::vector<CurvePoint> curve;
    MethodResult neural;
    std::optional<MethodResult> baseline;
    ShFitStats baselineFit;
    glm::uvec3 baselineProbes{0};
    size_t baselineTrainingSamples = 0;
    std::string baselineSamplesNote;  // where the baseline's training settings came from
    double baselineSeconds = 0.0;  // sampling + fit
    nlohmann::json assetMetadata;  // parsed META, or null
};

// Key of a reference render: the scene as imported (sceneHash), the camera, the image size, spp, path
// length and seed, and the renderer's version. 16 hex digits.
std::string referenceKey(const Scene& scene, const ValidateSettings& s, int width, int height);

// Runs the whole validation. `log` receives one line per step (may be empty). Throws std::runtime_error
// (bad reference file, evaluation failure) and IoError (cache write).
ValidationResult runValidation(const Scene& scene, const std::string& scenePath, NradAsset asset, const std::string& assetPath,
                               const ValidateSettings& settings, const std::function<void(const std::string&)>& log = {});

// The equal-error time on a convergence curve (see MethodResult); `extrapolated` says whether the value
// lies outside the curve.
double equalErrorTime(const std::vector<CurvePoint>& curve, double relMse, bool& extrapolated);

}  // namespace nrad
