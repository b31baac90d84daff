// Image comparison: the error metrics of the validation report, and the images that show where the error is.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "baker/render/image_io.h"

namespace nrad {

struct ImageMetrics {
    double rmse = 0.0;  // sqrt(mean over pixels and channels of (x - ref)^2)
    double relMse = 0.0;  // mean over pixels and channels of (x - ref)^2 / (ref^2 + 0.01)
    double psnr = 0.0;  // dB, of the tonemapped (exposure, clamp, sRGB) 8-bit-range images; inf if identical
    double meanRelativeError = 0.0;  // mean of |x - ref| / (|ref| + 0.01)
    // Structural similarity (Wang et al. 2004: 11 x 11 Gaussian window of sigma 1.5, C1 = 0.01^2, C2 = 0.03^2,
    // edges clamped, the mean over every pixel) of the luminances as displayed at the exposure a viewer adapts
    // to: the reference's log-average luminance mapped to middle grey (0.18), then sRGB-encoded and clamped;
    // 1 = identical. ssimExposure: that exposure in stops (whatever --exposure says: a dark room is judged as
    // the eye, adapted to it, sees it).
    double ssim = 1.0;
    double ssimExposure = 0.0;
};

// The exposure, in stops, that maps the image's log-average luminance to middle grey (0.18).
double viewerExposure(const Image& image);

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

// What the eye sees at the exposure a viewer adapts to (issue 38): errors of the light's shape and colour,
// which a whole-image relMSE can call good while every block is off. `mask[i]` marks the pixels that count
// (validate: those whose centre sees a surface that does not emit).
//
// Block figure: both images averaged over square blocks of `blockSize` pixels (validate: width / 16, 14
// pixels at 224 wide: well below a voxel's size on screen; the reference's own noise in a block is not
// negligible in dim light (docs/design.md), and validate reports it), over
// the blocks whose every pixel is masked and whose reference luminance is at least 1e-3 of the masked mean.
// Per block, the relative error of the mean luminance, and the tint: c = the block's mean RGB over the mean of
// its channels, max over channels |c_image - c_reference| (0 for a grey image of a grey scene, (max - min) /
// mean of a tinted block of a grey scene, roughly).
struct BlockFigure {
    int blockSize = 0;
    size_t blocks = 0;
    double rms = 0.0, worst = 0.0;  // of the luminance's relative error over the blocks
    // The worst block: its top-left pixel (-1 without blocks) and its signed error (< 0: the image darker).
    int worstX = -1, worstY = -1;
    double worstSigned = 0.0;
    double tintRms = 0.0, tintWorst = 0.0;
    // Largest (max - min) / mean of a block's mean RGB: the image's and the reference's (a grey scene's
    // reference is 0 up to its noise).
    double chroma = 0.0, referenceChroma = 0.0;
};
BlockFigure blockFigure(const Image& image, const Image& reference, const std::vector<uint8_t>& mask, int blockSize);

// Steps where the image crosses the partition's cells (voxels or kd-tree leaves), as the image shows them:
// for every pair of masked pixels `reach` pixels either side of a horizontal or vertical change of cell
// (cell[i]: the cell the pixel's centre sees, < 0 none), the image's luminance jump across it less the
// reference's jump at the same pixels (what the surface's own shading changes there cancels; the reference's
// noise averages out over a face). Pairs are grouped by the pair of cells; a group's step is the mean of
// those differences over the mean luminance of its pixels. Figures over the groups of at least `minPairs`
// pairs: rms (weighted by pairs) and worst |step|.
struct StepFigure {
    size_t faces = 0, pairs = 0;  // groups counted and their pairs
    double rms = 0.0, worst = 0.0;
};
StepFigure stepFigure(const Image& image, const Image& reference, const std::vector<int64_t>& cell, const std::vector<uint8_t>& mask,
                      int reach = 2, size_t minPairs = 16);

}  // namespace nrad
