// Image comparison: the error metrics of the validation report, and the images that show where the error is.
#pragma once

#include <string>
#include <vector>

#include "baker/render/image_io.h"

namespace nrad {

struct ImageMetrics {
    double rmse = 0.0;  // sqrt(mean over pixels and channels of (x - ref)^2)
    double relMse = 0.0;  // mean over pixels and channels of (x - ref)^2 / (ref^2 + 0.01)
    double psnr = 0.0;  // dB, of the tonemapped (exposure, clamp, sRGB) 8-bit-range images; inf if identical
    double meanRelativeError = 0.0;  // mean of |x - ref| / (|ref| + 0.01)
};

// Throws std::invalid_argument if the sizes differ. Non-finite pixels count as an error of the reference
// value (they should never occur; see NeuralRenderStats / RenderStats).
ImageMetrics compareImages(const Image& image, const Image& reference, float exposure = 0.0f);

// The paper's error image: (x - ref)^2 x 10, per channel.
Image squaredDifferenceImage(const Image& image, const Image& reference, float scale = 10.0f);

// False-colour map of the relative error |x - ref| / (|ref| + 0.01) (mean of the channels), log scale from
// 1e-3 (dark blue) through 1e-2, 1e-1 to 1 and above (dark red); linear RGB, ready for writePng.
Image relativeErrorMap(const Image& image, const Image& reference);

// The colour ramp of relativeErrorMap at t in [0, 1] (display sRGB, 0..1), for legends.
void errorRamp(float t, float srgb[3]);

// Errors of the pixels whose reference luminance lies in [lo, hi), one entry per decade that has pixels:
// relMSE as above (whose + 0.01 makes it an absolute error for dark pixels), and the purely relative
// error sqrt(mean((x - ref)^2 / ref^2)) over the channels with ref > 0.
struct DecadeError {
    double lo = 0.0, hi = 0.0;
    size_t pixels = 0;
    double relMse = 0.0;
    double relativeRms = 0.0;
};
std::vector<DecadeError> relMseByDecade(const Image& image, const Image& reference);

// Where the error lives. Per pixel: relMSE_i = mean over channels of (x - ref)^2 / (ref^2 + 0.01) (the
// image's relMSE is their mean) and the relative error e_i = mean over channels of |x - ref| / (|ref| + 0.01).
struct ErrorDistribution {
    double worst1PercentShare = 0.0;  // share of the summed relMSE_i held by the worst 1% of pixels (ceil)
    double medianRelativeError = 0.0;  // of e_i
    double p99RelativeError = 0.0;  // 99th percentile of e_i
};
ErrorDistribution errorDistribution(const Image& image, const Image& reference);

// relMSE over the pixels of each region: region[i] in [0, regionCount) names pixel i's region (or -1: none).
struct RegionError {
    size_t pixels = 0;
    double relMse = 0.0;  // mean relMSE_i over the region's pixels (0 if it has none)
    double shareOfImage = 0.0;  // the region's summed relMSE_i over the whole image's
};
std::vector<RegionError> relMseByRegion(const Image& image, const Image& reference, const std::vector<int>& region,
                                        int regionCount);

}  // namespace nrad
