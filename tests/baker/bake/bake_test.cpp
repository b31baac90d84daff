// A whole bake of the bundled Cornell box at small settings: finite weights, no network for empty voxels,
// held-out error within stated bounds, the paper's configuration under 8 KB, and byte-identical assets for
// one and two threads.
#include "baker/bake/baker.h"

#include <algorithm>
#include <cmath>

#include <gtest/gtest.h>

#include "baker/bake/voxel_grid.h"
#include "baker/scene/gltf_loader.h"
#include "baker/util/threads.h"
#include "support/test_paths.h"

namespace nrad {
namespace {

BakeSettings smallSettings() {
    BakeSettings s;
    s.grid = glm::uvec3(5);
    s.samples.points = 4000;
    s.samples.paths = 32;
    s.train.epochs = 400;
    s.train.patience = 100;
    s.samples.seed = s.train.seed = 7;
    return s;
}

TEST(Bake, CornellBoxSmall) {
    Scene scene = loadGltf(test::sourcePath("scenes/cornell-box/cornell-box.gltf"));
    BakeSettings s = smallSettings();
    BakeResult r = bakeScene(scene, s);
    // Every weight finite; scales finite and positive.
    for (float w : r.asset.weights) ASSERT_TRUE(std::isfinite(w));
    for (const format::VoxelEntry& v : r.asset.voxels) ASSERT_TRUE(std::isfinite(v.scale) && v.scale > 0.0f);
    // Networks exactly for the voxels with surface: none for the empty interior of the box.
    VoxelGrid grid(scene.bounds, s.grid);
    SurfacePieces pieces(scene.mesh, grid);
    std::vector<uint32_t> withSurface;
    for (uint32_t v = 0; v < grid.voxelCount(); ++v)
        if (!pieces.piecesOf(v).empty()) withSurface.push_back(v);
    std::vector<uint32_t> inAsset;
    for (const format::VoxelEntry& v : r.asset.voxels) inAsset.push_back(v.index);
    EXPECT_EQ(inAsset, withSurface);
    EXPECT_LT(inAsset.size(), 125u);
    EXPECT_EQ(r.asset.weights.size(), inAsset.size() * 120u);
    // Every voxel with surface reached the floor of samples.
    for (uint32_t v : withSurface) EXPECT_GE(r.sampleStats.perVoxel[v], s.samples.minSamplesPerVoxel) << v;
    EXPECT_EQ(r.sampleStats.droppedSamples, 0u);
    EXPECT_EQ(r.sampleStats.nonFinitePaths, 0u);
    // Stated bounds on the held-out relMSE: median below 0.01 over voxels; every voxel finite. (The voxels
    // holding the light's edge, radiance 17 next to a ceiling near 0.3, are far worse: reported, not hidden.)
    std::vector<double> err;
    for (const VoxelTrainResult& v : r.voxels) {
        ASSERT_TRUE(std::isfinite(v.heldOutRelMse));
        err.push_back(v.heldOutRelMse);
    }
    std::nth_element(err.begin(), err.begin() + long(err.size() / 2), err.end());
    EXPECT_LT(err[err.size() / 2], 0.01);
    // The asset decodes to what was baked (weights rounded to fp16).
    std::vector<uint8_t> bytes = format::encode(r.asset);
    format::Asset back;
    ASSERT_EQ(format::decode(bytes.data(), bytes.size(), back), format::DecodeStatus::Ok);
    ASSERT_EQ(back.weights.size(), r.asset.weights.size());
    for (size_t i = 0; i < back.weights.size(); ++i)
        ASSERT_NEAR(back.weights[i], r.asset.weights[i], 1e-3f * std::max(1.0f, std::abs(r.asset.weights[i])));
}

TEST(Bake, ByteIdenticalForOneAndTwoThreads) {
    Scene scene = loadGltf(test::sourcePath("scenes/cornell-box-glossy/cornell-box-glossy.gltf"));
    BakeSettings s = smallSettings();
    s.samples.points = 1500;
    s.samples.paths = 16;
    std::vector<uint8_t> one, two;
    {
        ThreadScope threads(1);
        one = format::encode(bakeScene(scene, s).asset);
    }
    {
        ThreadScope threads(2);
        two = format::encode(bakeScene(scene, s).asset);
    }
    EXPECT_EQ(one, two);
    s.samples.seed = s.train.seed = 8;
    EXPECT_NE(format::encode(bakeScene(scene, s).asset), one);  // the seed is really used
}

TEST(Bake, PaperConfigurationFitsIn8KB) {
    // 3x3x3 voxels of 9-9-3 at fp16, metadata included (the path count does not change the size).
    Scene scene = loadGltf(test::sourcePath("scenes/cornell-box/cornell-box.gltf"));
    BakeSettings s;
    s.samples.paths = 4;
    s.train.epochs = 50;
    BakeResult r = bakeScene(scene, s);
    std::vector<uint8_t> bytes = format::encode(r.asset);
    EXPECT_LE(r.asset.voxels.size(), 27u);
    EXPECT_GE(r.asset.voxels.size(), 20u);
    EXPECT_LT(bytes.size(), 8192u);
    EXPECT_FALSE(r.asset.metadata.empty());
}

}  // namespace
}  // namespace nrad
