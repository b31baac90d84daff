// Validation building blocks against closed forms: image metrics, the SH basis and probe fit, the
// equal-error interpolation, the bake curve aggregation and the SVG plot.
#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <random>

#include <gtest/gtest.h>
#include <nrad/format.h>

#include "baker/validate/metrics.h"
#include "baker/validate/report.h"
#include "baker/validate/sh_probes.h"
#include "baker/validate/validate.h"
#include "baker/bake/voxel_grid.h"
#include "baker/scene/gltf_loader.h"
#include "baker/util/threads.h"
#include "support/test_paths.h"
#include "support/test_scenes.h"

namespace nrad {
namespace {

Image constant(int w, int h, glm::vec3 v) {
    Image img(w, h);
    for (glm::vec3& p : img.pixels) p = v;
    return img;
}

TEST(Metrics, ClosedFormValues) {
    Image ref = constant(4, 2, glm::vec3(0.1f, 0.2f, 0.3f)), img = ref;
    for (glm::vec3& p : img.pixels) p += glm::vec3(0.1f);
    ImageMetrics m = compareImages(img, ref);
    EXPECT_NEAR(m.rmse, 0.1, 1e-6);
    double rel = (0.01 / (0.01 + 0.01) + 0.01 / (0.04 + 0.01) + 0.01 / (0.09 + 0.01)) / 3.0;
    EXPECT_NEAR(m.relMse, rel, 1e-6);
    EXPECT_NEAR(m.meanRelativeError, (0.1 / 0.11 + 0.1 / 0.21 + 0.1 / 0.31) / 3.0, 1e-6);
    // PSNR of tonemapped values: sRGB(0.2) - sRGB(0.1) etc.
    auto srgb = [](double v) { return v <= 0.0031308 ? 12.92 * v : 1.055 * std::pow(v, 1.0 / 2.4) - 0.055; };
    double mse = (std::pow(srgb(0.2) - srgb(0.1), 2) + std::pow(srgb(0.3) - srgb(0.2), 2) + std::pow(srgb(0.4) - srgb(0.3), 2)) / 3.0;
    EXPECT_NEAR(m.psnr, 10.0 * std::log10(1.0 / mse), 1e-3);
    EXPECT_TRUE(std::isinf(compareImages(ref, ref).psnr));
    EXPECT_EQ(compareImages(ref, ref).relMse, 0.0);
    EXPECT_THROW(compareImages(constant(2, 2, glm::vec3(0)), ref), std::invalid_argument);
    // A NaN pixel counts as zero radiance.
    Image nan = ref;
    nan.pixels[0] = glm::vec3(std::nanf(""));
    EXPECT_TRUE(std::isfinite(compareImages(nan, ref).relMse));
    EXPECT_GT(compareImages(nan, ref).relMse, 0.0);
}

TEST(Metrics, ErrorImagesAndDecades) {
    Image ref = constant(2, 1, glm::vec3(1.0f)), img = ref;
    ref.pixels[1] = glm::vec3(0.002f);
    img.pixels[0] = glm::vec3(1.5f);
    img.pixels[1] = glm::vec3(0.004f);
    Image sq = squaredDifferenceImage(img, ref);
    EXPECT_NEAR(sq.pixels[0].x, 10.0f * 0.25f, 1e-6f);
    EXPECT_NEAR(sq.pixels[1].x, 10.0f * 4e-6f, 1e-9f);
    std::vector<DecadeError> d = relMseByDecade(img, ref);
    ASSERT_EQ(d.size(), 2u);  // luminance 0.002 in [1e-3, 1e-2), 1 in [1, 10)
    EXPECT_DOUBLE_EQ(d[0].lo, 1e-3);
    EXPECT_NEAR(d[0].relativeRms, 1.0, 1e-5);  // 0.004 against 0.002: 100%
    EXPECT_DOUBLE_EQ(d[1].lo, 1.0);
    EXPECT_NEAR(d[1].relativeRms, 0.5, 1e-6);
    EXPECT_NEAR(d[1].relMse, 0.25 / 1.01, 1e-6);
    // The false-colour map runs from blue (small error) to red (large).
    Image map = relativeErrorMap(img, ref);
    EXPECT_GT(map.pixels[0].r, map.pixels[0].b);  // 50%: red end
    Image same = relativeErrorMap(ref, ref);
    EXPECT_GT(same.pixels[0].b, same.pixels[0].r);  // 0: blue end
}

// A field that is exactly an L2 SH function per probe, trilinear in space, is recovered exactly.
TEST(Metrics, ErrorDistributionAndRegionsOfKnownImages) {
    // 200 pixels of reference 1; pixel k is 1 + k / 200. Relative error e_k = (k / 200) / 1.01, relMSE_k =
    // (k / 200)^2 / 1.01: the median (nearest rank) is e_99, the 99th percentile e_197, and the worst 1% (2
    // pixels, k = 198, 199) hold (198^2 + 199^2) / sum k^2 of the relMSE.
    Image ref = constant(200, 1, glm::vec3(1.0f)), img = ref;
    for (int k = 0; k < 200; ++k) img.pixels[size_t(k)] = glm::vec3(1.0f + float(k) / 200.0f);
    ErrorDistribution d = errorDistribution(img, ref);
    auto e = [](int k) { return double(float(k) / 200.0f) / 1.01; };
    EXPECT_NEAR(d.medianRelativeError, e(99), 1e-6);
    EXPECT_NEAR(d.p99RelativeError, e(197), 1e-6);
    double sum = 0.0;
    for (int k = 0; k < 200; ++k) sum += double(k) * double(k);
    EXPECT_NEAR(d.worst1PercentShare, (198.0 * 198.0 + 199.0 * 199.0) / sum, 1e-4);
    // Regions: even pixels 0, odd pixels 1, pixel 0 in none.
    std::vector<int> region(200);
    for (int k = 0; k < 200; ++k) region[size_t(k)] = k % 2;
    region[0] = -1;
    std::vector<RegionError> r = relMseByRegion(img, ref, region, 2);
    ASSERT_EQ(r.size(), 2u);
    EXPECT_EQ(r[0].pixels, 99u);
    EXPECT_EQ(r[1].pixels, 100u);
    double even = 0.0, odd = 0.0;
    for (int k = 0; k < 200; ++k) (k % 2 ? odd : even) += std::pow(double(float(k) / 200.0f), 2) / 1.01;
    EXPECT_NEAR(r[0].relMse, even / 99.0, 1e-6);
    EXPECT_NEAR(r[1].relMse, odd / 100.0, 1e-6);
    EXPECT_NEAR(r[0].shareOfImage + r[1].shareOfImage, 1.0, 1e-9);  // pixel 0 has no error
    EXPECT_THROW(relMseByRegion(img, ref, std::vector<int>(3, 0), 2), std::invalid_argument);
}

// A quick bake of `scene` on a 2 x 2 x 2 grid (two threads), for the validation tests.
std::vector<uint8_t> quickBake(const Scene& scene, uint32_t points, uint32_t paths, int epochs, float blendBand = 0.0625f) {
    BakeSettings b;
    b.grid = glm::uvec3(2);
    b.samples.points = points;
    b.samples.paths = paths;
    b.train.epochs = epochs;
    b.train.patience = epochs;
    b.blendBand = blendBand;
    b.walls.enabled = false;  // a grid asset, which validates from memory (a tree needs its file); at grid 2 the
                              // box's floor would get a cell of its own
    return test::bakeBytes(scene, b, 2);
}

// A tiny validation of scene.cameras[0]: `width` pixels wide, a one-point convergence curve.
ValidateSettings tinyValidation(const Scene& scene, int width, int referenceSpp, int neuralSpp) {
    ValidateSettings s;
    s.camera = scene.cameras[0];
    s.width = width;
    s.referenceSpp = referenceSpp;
    s.curveMaxSpp = 1;
    s.neuralSpp = neuralSpp;
    return s;
}

// What the eye sees (issue 38): block, tint and step figures of images with a known bias.
TEST(Metrics, BlockFigureSeesABlockBiasAndATintThatRelMseCallsSmall) {
    // A grey reference of 64 x 64 pixels, 16 blocks of 16 x 16; every pixel masked but the top-left block's one.
    Image reference(64, 64);
    for (int y = 0; y < 64; ++y)
        for (int x = 0; x < 64; ++x) reference.at(x, y) = glm::vec3(0.5f + 0.004f * float(x));
    std::vector<uint8_t> mask(64 * 64, 1);
    mask[0] = 0;
    // Identical: nothing.
    BlockFigure same = blockFigure(reference, reference, mask, 16);
    EXPECT_EQ(same.blocks, 15u);  // the top-left block has an unmasked pixel
    EXPECT_EQ(same.rms, 0.0);
    EXPECT_EQ(same.tintWorst, 0.0);
    EXPECT_NEAR(same.referenceChroma, 0.0, 1e-7);
    // One block (of the 15 counted) 20% too bright: worst 0.2, rms 0.2 / sqrt(15).
    Image image = reference;
    for (int y = 16; y < 32; ++y)
        for (int x = 32; x < 48; ++x) image.at(x, y) *= 1.2f;
    BlockFigure bright = blockFigure(image, reference, mask, 16);
    EXPECT_NEAR(bright.worst, 0.2, 1e-6);
    EXPECT_NEAR(bright.rms, 0.2 / std::sqrt(15.0), 1e-6);
    EXPECT_EQ(bright.worstX, 32);  // where it is, and brighter
    EXPECT_EQ(bright.worstY, 16);
    EXPECT_NEAR(bright.worstSigned, 0.2, 1e-6);
    for (int y = 48; y < 64; ++y)
        for (int x = 0; x < 16; ++x) image.at(x, y) *= 0.7f;
    BlockFigure darker = blockFigure(image, reference, mask, 16);
    EXPECT_EQ(darker.worstX, 0);
    EXPECT_EQ(darker.worstY, 48);
    EXPECT_NEAR(darker.worstSigned, -0.3, 1e-6);
    image = reference;
    for (int y = 16; y < 32; ++y)
        for (int x = 32; x < 48; ++x) image.at(x, y) *= 1.2f;
    EXPECT_NEAR(bright.tintWorst, 0.0, 1e-6);  // brighter, not tinted
    // One block tinted: red +30%, blue -30%, its luminance nearly the same. c = rgb / mean: (1.3, 1, 0.7) -> tint 0.3.
    image = reference;
    for (int y = 32; y < 48; ++y)
        for (int x = 0; x < 16; ++x) image.at(x, y) *= glm::vec3(1.3f, 1.0f, 0.7f);
    BlockFigure tinted = blockFigure(image, reference, mask, 16);
    EXPECT_NEAR(tinted.tintWorst, 0.3, 1e-5);
    EXPECT_NEAR(tinted.chroma, 0.6, 1e-5);  // (1.3 - 0.7) / 1
    EXPECT_NEAR(tinted.referenceChroma, 0.0, 1e-7);
    EXPECT_LT(tinted.worst, 0.05);  // 0.2126 x 0.3 - 0.0722 x 0.3
    // A checkerboard of blocks +-10%: every block off by 10%, while relMSE (with its + 0.01) reads ~0.01.
    image = reference;
    for (int y = 0; y < 64; ++y)
        for (int x = 0; x < 64; ++x) image.at(x, y) *= ((x / 16 + y / 16) % 2) ? 1.1f : 0.9f;
    BlockFigure checker = blockFigure(image, reference, mask, 16);
    EXPECT_NEAR(checker.rms, 0.1, 1e-5);
    EXPECT_NEAR(checker.worst, 0.1, 1e-5);
    EXPECT_LT(compareImages(image, reference).relMse, 0.011);
    // Blocks whose reference is black (below 1e-3 of the masked mean) are not counted.
    Image dark = reference;
    for (int y = 48; y < 64; ++y)
        for (int x = 48; x < 64; ++x) dark.at(x, y) = glm::vec3(0.0f);
    EXPECT_EQ(blockFigure(reference, dark, mask, 16).blocks, 14u);
}

TEST(Metrics, SsimAtTheViewersExposureOfKnownImages) {
    // Constant images: no structure, SSIM is its luminance term (2 a b + C1) / (a^2 + b^2 + C1) of the displayed
    // values. The viewer's exposure maps the reference's luminance r to 0.18 whatever r is.
    auto srgb = [](double v) { return v <= 0.0031308 ? 12.92 * v : 1.055 * std::pow(v, 1.0 / 2.4) - 0.055; };
    for (float r : {0.001f, 1.0f, 500.0f}) {
        Image reference(40, 30), image(40, 30);
        for (glm::vec3& p : reference.pixels) p = glm::vec3(r);
        for (glm::vec3& p : image.pixels) p = glm::vec3(1.5f * r);
        ImageMetrics same = compareImages(reference, reference);
        EXPECT_NEAR(same.ssim, 1.0, 1e-12);
        EXPECT_NEAR(same.ssimExposure, std::log2(0.18 / (1e-6 + double(r))), 1e-5) << r;
        ImageMetrics m = compareImages(image, reference);
        const double a = srgb(0.18 * 1.5 * double(r) / (1e-6 + double(r))), b = srgb(0.18 * double(r) / (1e-6 + double(r)));
        EXPECT_NEAR(m.ssim, (2.0 * a * b + 1e-4) / (a * a + b * b + 1e-4), 1e-6) << r;
    }
    // Structure: a checkerboard of 4-pixel squares against a flat grey of the same mean loses the structure
    // term (SSIM far below 1); the same checkerboard 1% brighter keeps it (SSIM near 1).
    Image board(64, 64), flat(64, 64), brighter(64, 64);
    for (int y = 0; y < 64; ++y)
        for (int x = 0; x < 64; ++x) {
            const float v = ((x / 4 + y / 4) % 2) ? 0.3f : 0.1f;
            board.at(x, y) = glm::vec3(v);
            brighter.at(x, y) = glm::vec3(1.01f * v);
            flat.at(x, y) = glm::vec3(0.2f);
        }
    EXPECT_LT(compareImages(flat, board).ssim, 0.2);
    EXPECT_GT(compareImages(brighter, board).ssim, 0.99);
}

TEST(Metrics, StepFigureSeesAJumpAtACellFaceButNotAUniformBias) {
    // Two cells side by side (x < 20: cell 3, else cell 7), a third below (y >= 40: cell 9); the reference is
    // constant, so a pixel pair's reference jump is 0 and the image's jump is the step.
    const int w = 48, h = 48;
    Image reference(w, h);
    for (glm::vec3& p : reference.pixels) p = glm::vec3(0.5f);
    std::vector<int64_t> cell(size_t(w) * h);
    for (int y = 0; y < h; ++y)
        for (int x = 0; x < w; ++x) cell[size_t(y) * w + size_t(x)] = y >= 40 ? 9 : x < 20 ? 3 : 7;
    std::vector<uint8_t> mask(size_t(w) * h, 1);
    StepFigure none = stepFigure(reference, reference, cell, mask);
    EXPECT_EQ(none.rms, 0.0);
    EXPECT_EQ(none.faces, 3u);  // 3|7 (40 rows), 3|9 (20 columns), 7|9 (28 columns)
    EXPECT_EQ(none.pairs, 40u + 20u + 28u);
    // Cell 7 10% brighter: across 3|7 the image jumps by 0.05 against a level of (3 x 0.5 + 0.55) / 4; across
    // 7|9 likewise; 3|9 has no step.
    Image image = reference;
    for (int y = 0; y < h; ++y)
        for (int x = 0; x < w; ++x)
            if (cell[size_t(y) * w + size_t(x)] == 7) image.at(x, y) *= 1.1f;
    StepFigure step = stepFigure(image, reference, cell, mask);
    const double expected = 0.05 / (2.05 / 4.0);
    EXPECT_NEAR(step.worst, expected, 1e-5);
    EXPECT_NEAR(step.rms, expected * std::sqrt((40.0 + 28.0) / (40.0 + 20.0 + 28.0)), 1e-5);
    // The whole image 10% brighter: no step anywhere.
    Image uniform = reference;
    for (glm::vec3& p : uniform.pixels) p *= 1.1f;
    EXPECT_NEAR(stepFigure(uniform, reference, cell, mask).worst, 0.0, 1e-6);
    // A face with fewer than minPairs pairs is not counted; unmasked pixels drop their pairs.
    EXPECT_EQ(stepFigure(image, reference, cell, mask, 2, 30).faces, 1u);  // only 3|7's 40 (7|9 has 28)
    std::vector<uint8_t> left(mask);
    // Column 18 unmasked: the 3|7 pairs (x = 18 and 21 at reach 2) and one 3|9 pair (column 18) go.
    for (int y = 0; y < h; ++y) left[size_t(y) * w + 18] = 0;
    EXPECT_EQ(stepFigure(image, reference, cell, left).pairs, 19u + 28u);
}

TEST(Validate, AnAssetWithAnInjectedBiasOrTintIsFlagged) {
    // A small Cornell box bake on a 2 x 2 x 2 grid without blending, validated against its own neural image
    // (so every figure of the asset as baked is exactly 0), then with its x = 0 half (4 of 8 voxels) injected
    // with a 30% brighter output (the voxels' scale: a block bias with a step at the x mid-plane), and with a
    // 30% redder one (the last layer's red row and bias, where the red output is positive: a tint).
    Scene scene = loadGltf(test::sourcePath("scenes/cornell-box/cornell-box.gltf"));
    const std::vector<uint8_t> bytes = quickBake(scene, 4000, 4, 30, 0.0f);  // band 0: a step, not a blended ramp
    format::Asset decoded;
    ASSERT_EQ(format::decode(bytes.data(), bytes.size(), decoded), format::DecodeStatus::Ok);
    const size_t params = decoded.weights.size() / decoded.voxels.size();
    ASSERT_EQ(params, 120u);  // 9-9-3: W1 81, b1 9, W2 27, b2 3
    const std::string dir = test::temporaryDirectory();
    auto validateBytes = [&](const std::vector<uint8_t>& asset, const std::string& reference) {
        NradAsset a = nullptr;
        EXPECT_EQ(nradLoadFromMemory(asset.data(), asset.size(), NRAD_LOAD_COPY, &a, nullptr, 0), NRAD_OK);
        ValidateSettings s = tinyValidation(scene, 96, 1, 2);
        s.baseline = false;
        s.referenceImage = reference;
        ValidationResult r = runValidation(scene, "", a, "", s);
        nradReleaseAsset(a);
        return r;
    };
    writeExr(dir + "/own.exr", validateBytes(bytes, "").neural.image);
    const ValidationResult base = validateBytes(bytes, dir + "/own.exr");
    format::Asset brighter = decoded, redder = decoded;
    for (size_t k = 0; k < decoded.voxels.size(); ++k) {
        if (decoded.voxels[k].index % 2 != 0) continue;  // x = 1
        brighter.voxels[k].scale *= 1.3f;
        float* w = &redder.weights[k * params + 90];
        for (int i = 0; i < 9; ++i) w[i] *= 1.3f;  // W2's red row
        w[27] *= 1.3f;  // b2's red
    }
    const ValidationResult bright = validateBytes(format::encode(brighter), dir + "/own.exr");
    const ValidationResult red = validateBytes(format::encode(redder), dir + "/own.exr");
    const MethodResult &n0 = base.neural, &nb = bright.neural, &nr = red.neural;
    std::printf("blocks %zu, worst %.4f / %.4f / %.4f; steps %zu faces, worst %.4f / %.4f / %.4f; tint worst %.4f / %.4f / %.4f\n",
                n0.blocks.blocks, n0.blocks.worst, nb.blocks.worst, nr.blocks.worst, n0.steps.faces, n0.steps.worst, nb.steps.worst,
                nr.steps.worst, n0.blocks.tintWorst, nb.blocks.tintWorst, nr.blocks.tintWorst);
    EXPECT_GT(n0.blocks.blocks, 100u);
    EXPECT_GT(n0.steps.faces, 2u);
    EXPECT_EQ(n0.blocks.worst, 0.0);
    EXPECT_EQ(n0.blocks.tintWorst, 0.0);
    EXPECT_EQ(n0.steps.worst, 0.0);
    // Brighter: a block wholly in the injected half is 30% off; a face between the halves steps by
    // 0.3 L_a / ((2.3 L_a + 2 L_b) / 4) (0.26 where both sides are alike); the colour changes only in blocks
    // that straddle the halves and mix surfaces of different colours unequally.
    EXPECT_NEAR(nb.blocks.worst, 0.3, 0.002);
    EXPECT_GT(nb.blocks.rms, 0.1);
    EXPECT_GT(nb.steps.worst, 0.15);
    EXPECT_LT(nb.blocks.tintWorst, 0.03);
    // Redder: tinted, and seen as such.
    EXPECT_GT(nr.blocks.tintWorst, 0.1);
    EXPECT_GT(nr.blocks.tintRms, 0.03);
}

TEST(Validate, SeamFigureOfAKnownJumpAndTheBorderRegion) {
    // A plane split by the grid's face x = 0 into two voxels whose networks output the constants 1 and 2:
    // every sample across the face sees a jump of 1 around a mean of 1.5, relMSE 1 / (1.5^2 + 0.01).
    Scene scene = test::makeLitPlane(0.5f, 1.0f);
    VoxelGrid grid(scene.bounds, glm::uvec3(2, 1, 1));
    format::Asset a;
    a.header.flags = format::kFlagScatteredRadiance;
    a.grid = grid.grid();
    a.topology.outputTransform = format::OutputTransform::Exponential;
    const size_t params = a.topology.parameterCount();
    for (uint32_t v = 0; v < 2; ++v) {
        a.voxels.push_back({v, 1.0f});
        std::vector<float> w(params, 0.0f);
        for (size_t c = 0; c < 3; ++c) w[params - 3 + c] = std::log1p(float(v + 1));  // output bias: y = log(1 + L)
        a.weights.insert(a.weights.end(), w.begin(), w.end());
    }
    std::vector<uint8_t> bytes = format::encode(a);
    NradAsset asset = nullptr;
    ASSERT_EQ(nradLoadFromMemory(bytes.data(), bytes.size(), NRAD_LOAD_COPY, &asset, nullptr, 0), NRAD_OK);
    Accel accel(scene);
    const FirstHits hits = firstHits(scene, accel, scene.cameras[0], 64, 64, eval::Partition(a));
    SeamFigure f = seamFigure(hits, eval::Partition(a), asset);
    nradReleaseAsset(asset);
    {  // the same two voxels as the leaves of a kd-tree: the same figure
        format::Asset t = a;
        t.header.flags |= format::kFlagTree;
        t.tree = format::uniformTree(t.grid.dims);
        t.leafCount = 2;
        const std::vector<uint8_t> tb = format::encode(t);
        NradAsset ta = nullptr;
        ASSERT_EQ(nradLoadFromMemory(tb.data(), tb.size(), NRAD_LOAD_COPY, &ta, nullptr, 0), NRAD_OK);
        const SeamFigure g = seamFigure(firstHits(scene, accel, scene.cameras[0], 64, 64, eval::Partition(t)), eval::Partition(t), ta);
        nradReleaseAsset(ta);
        EXPECT_EQ(g.points, f.points);
        EXPECT_EQ(g.relMse, f.relMse);
    }
    EXPECT_GT(f.points, 20u);
    EXPECT_NEAR(f.relMse, 1.0 / (1.5 * 1.5 + 0.01), 2e-3);
    EXPECT_NEAR(f.meanRelativeJump, 1.0 / (1.5 + 0.01), 2e-3);
    // The voxel-border region: the two pixel columns either side of x = 0, nothing else.
    std::vector<int> region = pixelRegions(hits);
    for (int y = 0; y < 64; ++y)
        for (int x = 0; x < 64; ++x) EXPECT_EQ(region[size_t(y * 64 + x)], x == 31 || x == 32 ? 1 : 2) << x << ", " << y;
}

TEST(Validate, PixelsKnowTheirMaterialAndItsShareOfTheError) {
    // The lit plane's two triangles get two materials: triangle 0 holds the points with x > y. Every pixel's
    // first hit names the material of the triangle it lies on, and an image wrong only on material 1's pixels
    // puts all of its relMSE there.
    Scene scene = test::makeLitPlane(0.5f, 1.0f);
    scene.materials.push_back(scene.materials[0]);
    scene.materials[1].name = "second";
    scene.mesh.materialIds = {0, 1};
    VoxelGrid grid(scene.bounds, glm::uvec3(1, 1, 1));
    format::Asset a;
    a.grid = grid.grid();
    Accel accel(scene);
    const FirstHits hits = firstHits(scene, accel, scene.cameras[0], 32, 32, eval::Partition(a));
    Image ref = constant(32, 32, glm::vec3(1.0f)), img = ref;
    size_t second = 0;
    for (size_t i = 0; i < hits.material.size(); ++i) {
        const glm::vec3 p = hits.points[i];
        ASSERT_TRUE(std::isfinite(p.x)) << i;  // the plane fills the view
        if (std::abs(p.x - p.y) > 1e-3f) {
            EXPECT_EQ(hits.material[i], p.x > p.y ? 0 : 1) << p.x << ", " << p.y;
        }
        if (hits.material[i] == 1) {
            img.pixels[i] = glm::vec3(2.0f);
            ++second;
        }
    }
    EXPECT_GT(second, 400u);
    EXPECT_LT(second, 624u);
    std::vector<RegionError> m = relMseByRegion(img, ref, hits.material, 2);
    EXPECT_EQ(m[0].pixels + m[1].pixels, 32u * 32u);
    EXPECT_EQ(m[1].pixels, second);
    EXPECT_EQ(m[0].relMse, 0.0);
    EXPECT_NEAR(m[1].relMse, 1.0 / 1.01, 1e-6);
    EXPECT_NEAR(m[1].shareOfImage, 1.0, 1e-9);
    // The sky: no material.
    Scene empty = scene;
    empty.cameras[0].position = glm::vec3(0, 0, -5);  // looking away from the plane
    const FirstHits none = firstHits(empty, accel, empty.cameras[0], 8, 8, eval::Partition(a));
    for (int k : none.material) {
        EXPECT_EQ(k, -1);
    }
}

TEST(ShProbes, FitRecoversAnExactProbeField) {
    ShProbeGrid truth;
    truth.dims = {3, 2, 2};
    truth.lower = {-1, 0, 0};
    truth.upper = {2, 1, 3};
    std::mt19937 rng(3);
    std::uniform_real_distribution<float> u(-1.0f, 1.0f), u01(0.0f, 1.0f);
    truth.coeffs.resize(truth.probeCount() * 27);
    for (float& c : truth.coeffs) c = u(rng);
    for (size_t p = 0; p < truth.probeCount(); ++p) truth.coeffs[p * 27] = truth.coeffs[p * 27 + 9] = truth.coeffs[p * 27 + 18] = 8.0f;
    std::vector<TrainingSample> samples;
    for (int i = 0; i < 4000; ++i) {
        TrainingSample s;
        for (int k = 0; k < 3; ++k) s.position[k] = truth.lower[k] + u01(rng) * (truth.upper[k] - truth.lower[k]);
        s.wo = glm::normalize(glm::vec3(u(rng), u(rng), u(rng)));
        s.normal = s.wo;
        s.radiance = truth.evaluate(s.position, s.wo);
        ASSERT_GT(s.radiance.x, 0.0f);  // no clamping in play
        s.voxel = 0;
        samples.push_back(s);
    }
    ShFitStats st;
    ShProbeGrid fit = fitShProbeGrid(samples, truth.lower, truth.upper, truth.dims, &st, 1e-9);
    EXPECT_LT(st.relativeResidual, 1e-6);
    for (size_t i = 0; i < truth.coeffs.size(); ++i) EXPECT_NEAR(fit.coeffs[i], truth.coeffs[i], 8e-3f) << i;  // fp16 rounding
    EXPECT_LT(st.trainRelMse, 1e-5);
}

// Random samples of a smooth field over a lattice of many probes (several blocks of the fit's sums).
std::vector<TrainingSample> randomFieldSamples(const glm::vec3& lower, const glm::vec3& upper, size_t count, uint32_t seed) {
    std::mt19937 rng(seed);
    std::uniform_real_distribution<float> u(-1.0f, 1.0f), u01(0.0f, 1.0f);
    std::vector<TrainingSample> samples(count);
    for (TrainingSample& s : samples) {
        for (int k = 0; k < 3; ++k) s.position[k] = lower[k] + u01(rng) * (upper[k] - lower[k]);
        s.wo = glm::normalize(glm::vec3(u(rng), u(rng), u(rng)));
        s.normal = s.wo;
        const float shade = 1.0f + 0.5f * std::sin(s.position.x) * std::cos(2.0f * s.position.y) + 0.3f * s.wo.z;
        s.radiance = glm::vec3(shade, 0.5f * shade + 0.1f * u01(rng), 2.0f * u01(rng));
        s.voxel = 0;
    }
    return samples;
}

TEST(ShProbes, FitIsTheSameForAnyThreadCountAndReportsRisingProgress) {
    const glm::vec3 lower(-3, 0, 1), upper(5, 4, 6);
    const glm::uvec3 dims(10, 8, 7);  // 560 probes, 15,120 unknowns
    const std::vector<TrainingSample> samples = randomFieldSamples(lower, upper, 12000, 5);
    ShFitStats one, many;
    ShProbeGrid a, b;
    std::vector<double> fractions;
    {
        ThreadScope scope(1);
        a = fitShProbeGrid(samples, lower, upper, dims, &one);
    }
    {
        ThreadScope scope(4);
        b = fitShProbeGrid(samples, lower, upper, dims, &many, 1e-4, [&](double f) { fractions.push_back(f); });
    }
    ASSERT_EQ(a.coeffs.size(), b.coeffs.size());
    EXPECT_EQ(std::memcmp(a.coeffs.data(), b.coeffs.data(), a.coeffs.size() * sizeof(float)), 0);
    EXPECT_EQ(one.iterations, many.iterations);
    EXPECT_EQ(one.relativeResidual, many.relativeResidual);
    EXPECT_EQ(one.trainRelMse, many.trainRelMse);
    EXPECT_GT(one.iterations, 1) << one.iterations;
    EXPECT_LT(one.relativeResidual, 1e-2);  // stopped by the residual or by the objective's stall
    ASSERT_FALSE(fractions.empty());
    for (size_t i = 1; i < fractions.size(); ++i) EXPECT_GT(fractions[i], fractions[i - 1]);
    EXPECT_GT(fractions.front(), 0.0);
    EXPECT_EQ(fractions.back(), 1.0);
    // No samples: every coefficient zero.
    ShFitStats none;
    ShProbeGrid empty = fitShProbeGrid({}, lower, upper, dims, &none);
    for (float c : empty.coeffs) EXPECT_EQ(c, 0.0f);
    EXPECT_EQ(none.iterations, 0);
}

TEST(ShProbes, EveryFitKernelGivesThePlainFitsBits) {
    // The fit compiled per ISA: the same bits as the plain one on every kernel the CPU has (the relative
    // residual, a double, shows any difference in the unknowns before the fp16 rounding hides it).
    const glm::vec3 lower(-3, 0, 1), upper(5, 4, 6);
    const glm::uvec3 dims(9, 8, 7);  // odd and even counts of cells per axis
    const std::vector<TrainingSample> samples = randomFieldSamples(lower, upper, 9000, 6);
    const std::vector<std::string> kernels = shFitKernels();
    ASSERT_FALSE(kernels.empty());
    EXPECT_EQ(kernels.back(), "plain");
    ShFitStats plain;
    const ShProbeGrid reference = fitShProbeGrid(samples, lower, upper, dims, &plain, 1e-4, {}, "plain");
    EXPECT_GT(plain.iterations, 1);
    for (const std::string& kernel : kernels) {
        ShFitStats st;
        const ShProbeGrid g = fitShProbeGrid(samples, lower, upper, dims, &st, 1e-4, {}, kernel);
        EXPECT_EQ(std::memcmp(g.coeffs.data(), reference.coeffs.data(), g.coeffs.size() * sizeof(float)), 0) << kernel;
        EXPECT_EQ(st.iterations, plain.iterations) << kernel;
        EXPECT_EQ(st.relativeResidual, plain.relativeResidual) << kernel;
        EXPECT_EQ(st.trainRelMse, plain.trainRelMse) << kernel;
    }
    EXPECT_THROW(fitShProbeGrid(samples, lower, upper, dims, nullptr, 1e-4, {}, "sse9"), std::invalid_argument);
}

TEST(Validate, ReferenceKeyFollowsWhatTheImageDependsOn) {
    // The lit plane under a sun and a sky. Whether the engine draws the sun (--runtime-direct) changes what an
    // asset holds, not the path-traced reference: the key stays. Everything the image depends on moves it.
    Scene scene = test::makeLitPlane(0.5f, 1.0f);
    PunctualLight sun;
    sun.type = PunctualLight::Type::Directional;
    sun.name = "sun";
    sun.direction = glm::normalize(glm::vec3(-0.3f, -0.2f, -1.0f));
    sun.intensity = glm::vec3(3.0f);
    scene.lights.push_back(sun);
    scene.environment.kind = Environment::Kind::Constant;
    scene.environment.color = glm::vec3(0.5f);
    Texture checker;  // a base colour texture, so that texture coordinates and transforms matter
    checker.width = 2;
    checker.height = 1;
    checker.texels.push_back(glm::vec4(0.2f, 0.3f, 0.4f, 1.0f));
    checker.texels.push_back(glm::vec4(0.9f, 0.8f, 0.7f, 1.0f));
    scene.textures.push_back(checker);
    scene.materials[0].baseColorTexture.texture = 0;
    ValidateSettings s;
    s.camera = scene.cameras[0];
    const std::string key = referenceKey(scene, s, 64, 48);
    EXPECT_EQ(key.size(), 16u);
    EXPECT_EQ(referenceKey(scene, s, 64, 48), key);
    {
        Scene mixed = scene;
        mixed.lights[0].runtimeDirect = true;
        EXPECT_EQ(referenceKey(mixed, s, 64, 48), key);
        EXPECT_NE(sceneHash(mixed), sceneHash(scene));  // the asset's scene check does tell them apart
        mixed.lights[0].name = "renamed";
        EXPECT_EQ(referenceKey(mixed, s, 64, 48), key);
    }
    {  // settings of the validation that the reference does not use
        ValidateSettings t = s;
        t.neuralSpp = 16;
        t.curveMaxSpp = 8;
        t.exposure = 2.0f;
        t.baseline = false;
        t.baselinePointsPerProbe = 7;
        t.baselinePathsPerProbe = 3;
        t.cacheDir = "/elsewhere";
        EXPECT_EQ(referenceKey(scene, t, 64, 48), key);
    }
    std::vector<std::pair<std::string, std::string>> others;
    auto withSettings = [&](const std::string& what, auto change) {
        ValidateSettings t = s;
        change(t);
        others.push_back({what, referenceKey(scene, t, 64, 48)});
    };
    withSettings("spp", [](ValidateSettings& t) { t.referenceSpp = 1024; });
    withSettings("seed", [](ValidateSettings& t) { t.seed = 1; });
    withSettings("max depth", [](ValidateSettings& t) { t.maxDepth = 6; });
    withSettings("camera position", [](ValidateSettings& t) { t.camera.position.x += 0.25f; });
    withSettings("camera orientation", [](ValidateSettings& t) { t.camera.worldFromCamera[0][1] = 0.01f; });
    withSettings("camera size", [](ValidateSettings& t) { t.camera.ymag = 2.0f; });
    withSettings("camera type", [](ValidateSettings& t) { t.camera.type = Camera::Type::Perspective; });
    others.push_back({"width", referenceKey(scene, s, 65, 48)});
    others.push_back({"height", referenceKey(scene, s, 64, 49)});
    auto withScene = [&](const std::string& what, auto change) {
        Scene t = scene;
        change(t);
        others.push_back({what, referenceKey(t, s, 64, 48)});
    };
    withScene("sun intensity", [](Scene& t) { t.lights[0].intensity = glm::vec3(4.0f); });
    withScene("sun direction", [](Scene& t) { t.lights[0].direction = glm::vec3(0, 0, -1); });
    withScene("sun angle", [](Scene& t) { t.lights[0].cosAngularRadius = 0.9999f; });
    withScene("no sun", [](Scene& t) { t.lights.clear(); });
    withScene("sky colour", [](Scene& t) { t.environment.color = glm::vec3(0.6f); });
    withScene("sky intensity", [](Scene& t) { t.environment.intensity = 2.0f; });
    withScene("no sky", [](Scene& t) { t.environment.kind = Environment::Kind::None; });
    withScene("albedo", [](Scene& t) { t.materials[0].baseColor = glm::vec3(0.6f); });
    withScene("alpha cutoff", [](Scene& t) { t.materials[0].alphaCutoff = 0.25f; });
    withScene("transmission", [](Scene& t) { t.materials[0].transmission = 0.5f; });
    withScene("texture transform", [](Scene& t) { t.materials[0].baseColorTexture.scale = glm::vec2(2.0f); });
    withScene("uv", [](Scene& t) { t.mesh.uv0[1] = glm::vec2(1.0f, 0.0f); });
    withScene("texel", [](Scene& t) { t.textures[0].texels[1].x = 0.5f; });
    withScene("wrap mode", [](Scene& t) { t.textures[0].wrapS = WrapMode::ClampToEdge; });
    withScene("position", [](Scene& t) { t.mesh.positions[0].z = 0.01f; });
    for (size_t i = 0; i < others.size(); ++i) {
        EXPECT_NE(others[i].second, key) << others[i].first;
        for (size_t j = 0; j < i; ++j) EXPECT_NE(others[i].second, others[j].second) << others[i].first << " / " << others[j].first;
    }
}

TEST(Validate, BaselineTrainsOnABudgetPerProbeTheSameForAnyThreads) {
    // A small Cornell box bake; its baseline regenerates the bake's samples, the first `perProbe` x probes of
    // its points (plus the sampling floor), and is byte-identical for one thread and several.
    Scene scene = loadGltf(test::sourcePath("scenes/cornell-box/cornell-box.gltf"));
    const std::vector<uint8_t> bytes = quickBake(scene, 20000, 2, 20);
    NradAsset asset = nullptr;
    ASSERT_EQ(nradLoadFromMemory(bytes.data(), bytes.size(), NRAD_LOAD_COPY, &asset, nullptr, 0), NRAD_OK);
    ValidateSettings s = tinyValidation(scene, 24, 2, 1);
    s.baselinePointsPerProbe = 20;
    s.baselineMinPoints = 0;
    std::vector<std::string> lines;
    ValidationResult one, many, all, floored, fewerPaths;
    {
        ThreadScope scope(1);
        one = runValidation(scene, "", asset, "", s, [&](const std::string& line) { lines.push_back(line); });
    }
    {
        ThreadScope scope(3);
        many = runValidation(scene, "", asset, "", s);
        s.baselineMinPoints = 40000;  // the floor above the bake's points: every point
        floored = runValidation(scene, "", asset, "", s);
        s.baselineMinPoints = 0;
        s.baselinePointsPerProbe = 0;  // the bake's every point
        all = runValidation(scene, "", asset, "", s);
        // Every point, but a paths' budget of one path a point: the bake's 2 are halved.
        s.baselineMinPaths = 0;
        s.baselinePathsPerProbe = uint32_t(all.baselineTrainingSamples * 3 / 2 /
                                           (size_t(all.baselineProbes.x) * all.baselineProbes.y * all.baselineProbes.z));
        fewerPaths = runValidation(scene, "", asset, "", s);
    }
    nradReleaseAsset(asset);
    ASSERT_TRUE(one.baseline && many.baseline && all.baseline && floored.baseline && fewerPaths.baseline);
    const size_t probes = size_t(one.baselineProbes.x) * one.baselineProbes.y * one.baselineProbes.z;
    EXPECT_LT(20 * probes, 20000u);  // the budget is what limits
    EXPECT_GT(one.baselineTrainingSamples, 20 * probes / 2);  // less the points no viewer sees
    EXPECT_LE(one.baselineTrainingSamples, 20 * probes + 8 * 64);  // plus at most the floor of the 8 voxels
    // The bake's 2 paths a point and no more: noisy targets get no extra paths here (2 paths are noisy enough
    // that the bake's default would have given most points 4x).
    EXPECT_GE(one.baselineTrainingPaths, 2 * one.baselineTrainingSamples);
    EXPECT_LE(one.baselineTrainingPaths, 2 * (20 * probes + 8 * 64));
    EXPECT_NE(one.baselineSamplesNote.find("20 per probe"), std::string::npos) << one.baselineSamplesNote;
    EXPECT_EQ(one.baselineSamplesNote.find("paths a point"), std::string::npos) << one.baselineSamplesNote;  // within 2^21
    EXPECT_GT(all.baselineTrainingSamples, 15000u);
    EXPECT_EQ(all.baselineSamplesNote.find("per probe"), std::string::npos) << all.baselineSamplesNote;
    EXPECT_EQ(floored.baselineTrainingSamples, all.baselineTrainingSamples);
    EXPECT_EQ(floored.baselineSamplesNote.find("per probe"), std::string::npos) << floored.baselineSamplesNote;
    EXPECT_NE(fewerPaths.baselineSamplesNote.find("1 paths a point, not 2"), std::string::npos) << fewerPaths.baselineSamplesNote;
    // The same points (a point is dropped only when every path is non-finite, or hidden from every view),
    // other targets.
    EXPECT_NEAR(double(fewerPaths.baselineTrainingSamples), double(all.baselineTrainingSamples), 0.001 * all.baselineTrainingSamples);
    EXPECT_NE(fewerPaths.baselineFit.trainRelMse, all.baselineFit.trainRelMse);
    EXPECT_EQ(many.baselineTrainingSamples, one.baselineTrainingSamples);
    EXPECT_EQ(many.baselineFit.iterations, one.baselineFit.iterations);
    EXPECT_EQ(many.baselineFit.trainRelMse, one.baselineFit.trainRelMse);
    const std::vector<glm::vec3>&p = one.baseline->image.pixels, &q = many.baseline->image.pixels;
    ASSERT_EQ(p.size(), q.size());
    EXPECT_EQ(std::memcmp(p.data(), q.data(), p.size() * sizeof(glm::vec3)), 0);
    // Progress: the sampling and the fit each reach 100%.
    auto said = [&](const std::string& what) {
        for (const std::string& l : lines)
            if (l.find(what) != std::string::npos) return true;
        return false;
    };
    EXPECT_TRUE(said("baseline: sampling 100%"));
    EXPECT_TRUE(said("baseline: fit 100%"));
}

TEST(Validate, BaselineProbesComeFromTheCacheWhileNothingTheyDependOnChanges) {
    // Issue 37: the probes depend on the scene as baked and the samples' settings, not on the view, the spp or the
    // exposure; validating the asset again reads them from the cache (the same bits), a change of what they
    // depend on fits them again, and a damaged entry is fitted again and replaced.
    namespace fs = std::filesystem;
    Scene scene = loadGltf(test::sourcePath("scenes/cornell-box/cornell-box.gltf"));
    const std::vector<uint8_t> bytes = quickBake(scene, 20000, 2, 20);
    NradAsset asset = nullptr;
    ASSERT_EQ(nradLoadFromMemory(bytes.data(), bytes.size(), NRAD_LOAD_COPY, &asset, nullptr, 0), NRAD_OK);
    ValidateSettings s = tinyValidation(scene, 24, 2, 1);
    s.cacheDir = test::temporaryDirectory();
    const ValidationResult first = runValidation(scene, "", asset, "", s);
    ValidateSettings other = s;  // another view, exposure and spp: the same probes
    other.camera.position += glm::vec3(0.05f, 0.0f, 0.0f);
    other.exposure = 1.0f;
    other.neuralSpp = 2;
    std::vector<std::string> lines;
    const ValidationResult again = runValidation(scene, "", asset, "", other, [&](const std::string& l) { lines.push_back(l); });
    ValidateSettings uncached = other;
    uncached.cacheDir.clear();
    const ValidationResult fresh = runValidation(scene, "", asset, "", uncached);
    ValidateSettings fewer = s;  // fewer paths a point: other samples
    fewer.baselineMinPaths = 0;
    fewer.baselinePathsPerProbe = 1;
    const ValidationResult refit = runValidation(scene, "", asset, "", fewer);
    ASSERT_TRUE(first.baseline && again.baseline && fresh.baseline && refit.baseline);
    EXPECT_EQ(first.baselineSource, "fitted");
    ASSERT_FALSE(first.baselineCacheFile.empty());
    EXPECT_TRUE(fs::exists(first.baselineCacheFile));
    EXPECT_EQ(again.baselineSource, "cache");
    EXPECT_EQ(again.baselineCacheFile, first.baselineCacheFile);
    bool said = false;
    for (const std::string& l : lines) said = said || l.find("baseline: probes from the cache") != std::string::npos;
    EXPECT_TRUE(said);
    EXPECT_EQ(again.baselineTrainingSamples, first.baselineTrainingSamples);
    EXPECT_EQ(again.baselineTrainingPaths, first.baselineTrainingPaths);
    EXPECT_EQ(again.baselineFit.iterations, first.baselineFit.iterations);
    EXPECT_EQ(again.baselineFit.trainRelMse, first.baselineFit.trainRelMse);
    EXPECT_EQ(again.baselineFittedSeconds, first.baselineSeconds);
    const nlohmann::json report = reportJson(again, nlohmann::json());
    EXPECT_EQ(report["baseline"]["source"], "cache");
    EXPECT_EQ(report["baseline"]["cache_file"], first.baselineCacheFile);
    EXPECT_EQ(report["baseline"]["sampling_and_fit_seconds"].get<double>(), first.baselineSeconds);
    EXPECT_EQ(report["baseline"]["seconds"].get<double>(), again.baselineSeconds);
    // The cached probes shade the other view exactly as probes fitted there and then.
    EXPECT_EQ(fresh.baselineSource, "fitted");
    EXPECT_TRUE(fresh.baselineCacheFile.empty());
    const std::vector<glm::vec3>&p = again.baseline->image.pixels, &q = fresh.baseline->image.pixels;
    ASSERT_EQ(p.size(), q.size());
    EXPECT_EQ(std::memcmp(p.data(), q.data(), p.size() * sizeof(glm::vec3)), 0);
    EXPECT_EQ(refit.baselineSource, "fitted");
    EXPECT_NE(refit.baselineCacheFile, first.baselineCacheFile);
    // A damaged entry (short, another magic, a NaN coefficient): fitted again, the same probes, the entry replaced.
    const std::string good = test::fileBytes(first.baselineCacheFile);
    ASSERT_GT(good.size(), 64u);
    std::string otherMagic = good, nanCoefficient = good;
    otherMagic[7] = '2';
    const float nan = std::nanf("");
    std::memcpy(&nanCoefficient[good.size() - 8], &nan, sizeof nan);
    for (const std::string& damaged : {good.substr(0, good.size() - 4), otherMagic, nanCoefficient}) {
        {
            std::ofstream f(first.baselineCacheFile, std::ios::binary | std::ios::trunc);
            f.write(damaged.data(), std::streamsize(damaged.size()));
        }
        const ValidationResult repaired = runValidation(scene, "", asset, "", s);
        EXPECT_EQ(repaired.baselineSource, "fitted");
        EXPECT_EQ(repaired.baselineFit.trainRelMse, first.baselineFit.trainRelMse);
        EXPECT_EQ(runValidation(scene, "", asset, "", s).baselineSource, "cache");
    }
    nradReleaseAsset(asset);

    // The key follows what the probes depend on: the engine-drawn lights (which the reference's key leaves out),
    // the samples, the sampling grid, the box, the lattice, demodulation; not the camera (it is not an input).
    BaselineKeyInputs in;
    in.samples.points = 1000;
    in.samples.paths = 8;
    in.samplingDims = glm::uvec3(3);
    in.lower = glm::vec3(-1.0f);
    in.upper = glm::vec3(1.0f);
    in.probes = glm::uvec3(4);
    Scene lit = test::makeLitPlane(0.5f, 1.0f);
    PunctualLight sun;
    sun.type = PunctualLight::Type::Directional;
    sun.direction = glm::vec3(0, 0, -1);
    sun.intensity = glm::vec3(3.0f);
    lit.lights.push_back(sun);
    const std::string key = baselineKey(lit, in);
    EXPECT_EQ(key.size(), 16u);
    EXPECT_EQ(baselineKey(lit, in), key);
    std::vector<std::string> keys = {key};
    Scene drawn = lit;
    drawn.lights[0].runtimeDirect = true;
    keys.push_back(baselineKey(drawn, in));
    Scene brighter = lit;
    brighter.lights[0].intensity = glm::vec3(4.0f);
    keys.push_back(baselineKey(brighter, in));
    auto with = [&](auto change) {
        BaselineKeyInputs t = in;
        change(t);
        keys.push_back(baselineKey(lit, t));
    };
    with([](BaselineKeyInputs& t) { t.samples.points = 1001; });
    with([](BaselineKeyInputs& t) { t.samples.minSamplesPerVoxel = 32; });
    with([](BaselineKeyInputs& t) { t.samples.dropHidden = false; });
    with([](BaselineKeyInputs& t) { t.samples.neeWarmupPaths = 1000; });
    with([](BaselineKeyInputs& t) { t.samples.firstPoint = 7; });
    with([](BaselineKeyInputs& t) { t.samples.generation = 1; });
    with([](BaselineKeyInputs& t) { t.samples.extraPathsFactor = 1; });
    with([](BaselineKeyInputs& t) { t.samples.noisyRelativeError = 0.2f; });
    with([](BaselineKeyInputs& t) { t.samplingDims.x = 4; });
    with([](BaselineKeyInputs& t) { t.upper.y = 1.5f; });
    with([](BaselineKeyInputs& t) { t.samples.paths = 4; });
    with([](BaselineKeyInputs& t) { t.samples.seed = 1; });
    with([](BaselineKeyInputs& t) { t.samples.maxDepth = 6; });
    with([](BaselineKeyInputs& t) { t.samplingDims.z = 4; });
    with([](BaselineKeyInputs& t) { t.lower.x = -1.5f; });
    with([](BaselineKeyInputs& t) { t.probes.y = 5; });
    with([](BaselineKeyInputs& t) { t.demodulated = true; });
    for (size_t i = 0; i < keys.size(); ++i)
        for (size_t j = 0; j < i; ++j) EXPECT_NE(keys[i], keys[j]) << i << " / " << j;
}

TEST(ShProbes, BasisIsOrthonormalOnTheSphere) {
    // Monte Carlo over a Fibonacci sphere: <Y_i, Y_j> = delta_ij.
    const int n = 20000;
    double g[9][9] = {};
    for (int s = 0; s < n; ++s) {
        double z = 1.0 - (2.0 * s + 1.0) / n, r = std::sqrt(1.0 - z * z), phi = s * 2.399963229728653;
        float y[9];
        shBasis(glm::vec3(float(r * std::cos(phi)), float(r * std::sin(phi)), float(z)), y);
        for (int i = 0; i < 9; ++i)
            for (int j = 0; j < 9; ++j) g[i][j] += double(y[i]) * y[j] * 4.0 * M_PI / n;
    }
    for (int i = 0; i < 9; ++i)
        for (int j = 0; j < 9; ++j) EXPECT_NEAR(g[i][j], i == j ? 1.0 : 0.0, 2e-3) << i << "," << j;
}

TEST(ShProbes, DimsFitTheByteBudget) {
    glm::uvec3 d = probeDimsForBudget({0, 0, 0}, {1, 1, 1}, 6240);
    EXPECT_LE(size_t(d.x) * d.y * d.z * 54, 6240u);
    EXPECT_GT((size_t(d.x) * d.y * d.z + std::min({d.x * d.y, d.y * d.z, d.x * d.z})) * 54, 6240u);  // no whole layer more fits
    glm::uvec3 flat = probeDimsForBudget({0, 0, 0}, {4, 1, 1}, 6240);
    EXPECT_GT(flat.x, flat.y);
    EXPECT_EQ(probeDimsForBudget({0, 0, 0}, {1, 1, 1}, 10), glm::uvec3(2));  // at least 2 per axis
}

TEST(Validate, EqualErrorTimeInterpolatesLogLog) {
    std::vector<CurvePoint> curve;
    for (int k = 0; k < 5; ++k) {
        CurvePoint c;
        c.spp = 1 << k;
        c.seconds = 0.5 * c.spp;
        c.metrics.relMse = 0.4 / c.spp;  // error ~ 1 / time
        curve.push_back(c);
    }
    bool extrapolated = true;
    EXPECT_NEAR(equalErrorTime(curve, 0.4 / 3.0, extrapolated), 1.5, 1e-9);
    EXPECT_FALSE(extrapolated);
    EXPECT_NEAR(equalErrorTime(curve, 0.4 / 64.0, extrapolated), 32.0, 1e-9);  // beyond the curve, 1/time
    EXPECT_TRUE(extrapolated);
    EXPECT_NEAR(equalErrorTime(curve, 0.8, extrapolated), 0.25, 1e-9);  // worse than 1 spp
    EXPECT_TRUE(extrapolated);
}

TEST(Validate, ReferenceNoiseIsTheReferencesShareOfTheCurve) {
    // A path tracer of relMSE c / spp against the truth, measured against a reference of M spp: c / N + c / M.
    const double c = 1.5, M = 512.0;
    std::vector<CurvePoint> curve;
    for (int k = 0; k < 9; ++k) {
        CurvePoint p;
        p.spp = 1 << k;
        p.metrics.relMse = c / p.spp + c / M;
        curve.push_back(p);
    }
    EXPECT_NEAR(referenceNoise(curve, int(M)), c / M, 1e-12);
    EXPECT_NEAR(referenceNoise(curve, 4096), (c / 256.0 + c / M) * 256.0 / (256.0 + 4096.0), 1e-12);  // another M: as measured
    EXPECT_EQ(referenceNoise({}, 512), 0.0);
}

// The reference's own noise in the block figure, estimated as validate does from an independent render of
// fewer paths, against the reference's block error measured against the truth itself.
TEST(Validate, ReferenceBlockNoiseIsTheReferencesShareOfACurveImagesBlocks) {
    const int W = 256, M = 512, S = 64, block = 16;
    const double sigma = 2.0;  // a path's relative standard deviation: the pixel's at N paths is sigma / sqrt(N)
    std::mt19937 rng(5);
    std::normal_distribution<double> normal(0.0, 1.0);
    Image truth(W, W), reference(W, W), curve(W, W);
    for (int y = 0; y < W; ++y)
        for (int x = 0; x < W; ++x) {
            const float v = 0.2f + 0.001f * float(x + y);
            truth.at(x, y) = glm::vec3(v);
            reference.at(x, y) = glm::vec3(float(v * (1.0 + sigma / std::sqrt(double(M)) * normal(rng))));
            curve.at(x, y) = glm::vec3(float(v * (1.0 + sigma / std::sqrt(double(S)) * normal(rng))));
        }
    const std::vector<uint8_t> mask(size_t(W) * W, 1);
    const double measured = blockFigure(reference, truth, mask, block).rms;  // what the reference's blocks are off by
    const double expected = sigma / std::sqrt(double(M) * block * block);  // 0.0055
    EXPECT_NEAR(measured, expected, 0.15 * expected);
    const double estimate = referenceBlockNoise(blockFigure(curve, reference, mask, block).rms, S, M);
    EXPECT_NEAR(estimate, measured, 0.15 * measured);
    // Without the split (the curve image's blocks as they read) it would be 3x too large.
    EXPECT_GT(blockFigure(curve, reference, mask, block).rms, 2.5 * measured);
    EXPECT_EQ(referenceBlockNoise(0.1, 0, M), 0.0);
    EXPECT_NEAR(referenceBlockNoise(0.3, 64, 512), 0.1, 1e-12);
}

TEST(Report, BakeCurveAggregatesVoxelsAndPlotsAreSvg) {
    nlohmann::json stats = {{"voxels",
                             {{{"curve_epoch_seconds_relmse", {{0, 0.1, 1.0}, {10, 0.2, 0.5}}}},
                              {{"curve_epoch_seconds_relmse", {{0, 0.15, 4.0}, {10, 0.3, 0.1}}}}}}};
    std::vector<BakeCurvePoint> c = bakeTrainingCurve(stats);
    ASSERT_EQ(c.size(), 4u);
    EXPECT_DOUBLE_EQ(c[0].seconds, 0.1);
    EXPECT_DOUBLE_EQ(c[0].meanRelMse, 2.5);  // second voxel not started: its first error
    EXPECT_DOUBLE_EQ(c[2].meanRelMse, 2.25);  // t = 0.2: 0.5 and 4.0
    EXPECT_DOUBLE_EQ(c[3].meanRelMse, 0.3);
    EXPECT_DOUBLE_EQ(c[3].medianRelMse, 0.3);
    EXPECT_TRUE(bakeTrainingCurve(nlohmann::json::object()).empty());
    std::string svg = svgLogLogPlot("t <&>", "x", "y", {{"a", "#000", {{1, 1}, {10, 0.1}}, true}, {"b", "red", {{-1, 1}}, false}});
    EXPECT_EQ(svg.rfind("<svg", 0), 0u);
    EXPECT_NE(svg.find("t &lt;&amp;&gt;"), std::string::npos);
    EXPECT_NE(svg.find("<polyline"), std::string::npos);
    EXPECT_NE(svg.find("</svg>"), std::string::npos);
}

}  // namespace
}  // namespace nrad
