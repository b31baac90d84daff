// A whole bake of the bundled Cornell box at small settings: finite weights, no network for empty voxels,
// held-out error within stated bounds, the paper's configuration under 8 KB, and byte-identical assets for
// one and two threads.
#include "baker/bake/baker.h"

#include <algorithm>
#include <cmath>
#include <cstdio>

#include <gtest/gtest.h>
#include <nrad/nrad.hpp>

#include "baker/bake/voxel_grid.h"
#include "baker/lights/light_sampler.h"
#include "baker/render/accel.h"
#include "baker/render/path_tracer.h"
#include "baker/render/surface.h"
#include "baker/render/neural_render.h"
#include "baker/scene/gltf_loader.h"
#include "baker/util/threads.h"
#include "support/test_paths.h"
#include "support/test_scenes.h"

namespace nrad {
namespace {

// A sharp directional light travelling along `direction` (normalised) with `intensity`.
PunctualLight directionalSun(const glm::vec3& direction, const glm::vec3& intensity) {
    PunctualLight sun;
    sun.type = PunctualLight::Type::Directional;
    sun.direction = glm::normalize(direction);
    sun.intensity = intensity;
    return sun;
}

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

// Points and paths left at 0 are chosen from the other settings, the same for `nrad bake` and a library caller.
TEST(Bake, AutomaticPointsAndPathsFollowTheOtherSettings) {
    BakeSettings s;
    EXPECT_EQ(s.samples.points, 0u);
    EXPECT_EQ(s.samples.paths, 0u);
    BakeSettings r = resolvedBakeSettings(s);
    EXPECT_EQ(r.samples.points, 160000u);  // the 3x3x3 grid's
    EXPECT_EQ(r.samples.paths, 32u);
    s.grid = glm::uvec3(6, 6, 3);
    EXPECT_EQ(resolvedBakeSettings(s).samples.points, 160000u * 108 / 27);  // the same density per cell
    s.grid = glm::uvec3(2);
    EXPECT_EQ(resolvedBakeSettings(s).samples.points, 160000u);  // never fewer
    s.training = TrainingMethod::Integral;
    s.grid = glm::uvec3(4);
    r = resolvedBakeSettings(s);
    EXPECT_EQ(r.samples.points, 1500u * 64);
    EXPECT_EQ(r.samples.paths, 4u);
    s.grid = glm::uvec3(2);
    EXPECT_EQ(resolvedBakeSettings(s).samples.points, 40000u);
    s.training = TrainingMethod::MonteCarlo;
    s.partition.budgetBytes = 64 << 10;  // 9-9-3 in fp16: 120 x 2 + 40 bytes a network, 234 of them
    EXPECT_EQ(resolvedBakeSettings(s).samples.points, 234u * (160000 / 27));  // a grid cell's density per network
    s.partition.budgetBytes = 1 << 20;
    EXPECT_EQ(resolvedBakeSettings(s).samples.points, 4000000u);  // the cap
    s.samples.points = 1234;  // given: kept
    s.samples.paths = 7;
    r = resolvedBakeSettings(s);
    EXPECT_EQ(r.samples.points, 1234u);
    EXPECT_EQ(r.samples.paths, 7u);
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
    const std::vector<uint8_t> one = test::bakeBytes(scene, s, 1);
    EXPECT_EQ(test::bakeBytes(scene, s, 2), one);
    s.samples.seed = s.train.seed = 8;
    EXPECT_NE(format::encode(bakeScene(scene, s).asset), one);  // the seed is really used
}

// Noisy targets get more paths (SampleSettings::extraPathsFactor): on the glossy box some points do, decided
// from each point's own estimates, so the bake stays byte-identical for any threads; factor 1 turns it off.
TEST(Bake, NoisyTargetsGetMorePathsTheSameForAnyThreads) {
    Scene scene = loadGltf(test::sourcePath("scenes/cornell-box-glossy/cornell-box-glossy.gltf"));
    BakeSettings s = smallSettings();
    s.samples.points = 1500;
    s.samples.paths = 16;
    s.samples.extraPathsFactor = 4;
    const BakeResult on = bakeScene(scene, s);
    EXPECT_EQ(format::encode(on.asset), test::bakeBytes(scene, s, 1));
    EXPECT_EQ(format::encode(on.asset), test::bakeBytes(scene, s, 2));
    EXPECT_GT(on.sampleStats.noisyPoints, 0u);
    EXPECT_LT(on.sampleStats.noisyPoints, on.sampleCount);
    // Each gets the paths that bring its error to the bound, at most 3 x 16 more: some fewer.
    EXPECT_GE(on.sampleStats.extraPaths, on.sampleStats.noisyPoints);
    EXPECT_LT(on.sampleStats.extraPaths, on.sampleStats.noisyPoints * 3 * 16);
    s.samples.extraPathsFactor = 1;
    const BakeResult off = bakeScene(scene, s);
    EXPECT_EQ(off.sampleStats.noisyPoints, 0u);
    EXPECT_GT(on.sampleStats.rays.total(), off.sampleStats.rays.total());
    EXPECT_NE(format::encode(on.asset), format::encode(off.asset));
}

// A noisy point's extra paths: those that bring its mean's relative standard error r (over its n estimates) to the
// bound b, paths x ((r / b)^2 - 1) rounded up, at most (factor - 1) x paths.
TEST(Bake, NoisyPointsGetThePathsThatBringTheirErrorToTheBound) {
    SampleSettings s;
    s.paths = 32;
    s.extraPathsFactor = 4;
    s.noisyRelativeError = 0.15f;
    // The sample variance of n = 32 estimates whose mean has the relative standard error r.
    auto extra = [&](double r, double mean) { return noisyExtraPaths(mean, r * r * 32.0 * mean * mean, 32, s); };
    EXPECT_EQ(extra(0.1, 2.0), 0u);
    EXPECT_EQ(extra(0.149, 2.0), 0u);
    EXPECT_EQ(extra(0.2, 2.0), 25u);  // 32 x (0.04 / 0.0225 - 1) = 24.9
    EXPECT_EQ(extra(0.2, 1e-6), 25u);  // relative: the same for a dim point
    EXPECT_EQ(extra(0.25, 2.0), 57u);  // 32 x 1.78 = 56.9
    EXPECT_EQ(extra(1.0, 2.0), 96u);  // capped at 3 x 32
    s.extraPathsFactor = 64;
    EXPECT_EQ(extra(1.0, 2.0), 1391u);  // 32 x (1 / 0.0225 - 1) = 1390.2, below 63 x 32
    EXPECT_EQ(noisyExtraPaths(0.0, 1.0, 32, s), 0u);  // no light: nothing to resolve
    EXPECT_EQ(noisyExtraPaths(2.0, 1e9, 1, s), 0u);  // one estimate: no variance to judge
    s.extraPathsFactor = 1;
    EXPECT_EQ(extra(1.0, 2.0), 0u);  // off
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


// A lamp alone in an empty room (issue 13): a 0.6 m square emitter of radiance (5, 3, 1), black itself (it
// scatters nothing), on the floor of a grey 2 m room. The networks store scattered radiance, so the asset
// on the lamp is ~0 although the lit floor beside it shares its voxel, and shading adds the lamp's emission
// back: the rendered lamp is its emission.
Scene lampInAnEmptyRoom() {
    Scene scene;
    scene.sourcePath = "<lamp in an empty room>";
    Material wall;
    wall.baseColor = glm::vec3(0.5f);
    wall.metallic = 0.0f;
    wall.specular = 0.0f;
    Material lamp = wall;
    lamp.baseColor = glm::vec3(0.0f);
    lamp.emission = glm::vec3(5.0f, 3.0f, 1.0f);
    scene.materials = {wall, lamp};
    TriangleMesh& mesh = scene.mesh;
    auto quad = [&](glm::vec3 a, glm::vec3 b, glm::vec3 c, glm::vec3 d, uint32_t material) {
        glm::vec3 n = glm::normalize(glm::cross(b - a, c - a));
        uint32_t first = uint32_t(mesh.positions.size());
        for (const glm::vec3& v : {a, b, c, d}) {
            mesh.positions.push_back(v);
            mesh.normals.push_back(n);
            mesh.uv0.emplace_back(0.0f);
            mesh.uv1.emplace_back(0.0f);
        }
        mesh.triangles.push_back({first, first + 1, first + 2});
        mesh.triangles.push_back({first, first + 2, first + 3});
        mesh.materialIds.push_back(material);
        mesh.materialIds.push_back(material);
    };
    const float S = 2.0f;  // the room [0, S]^3, every wall facing inwards
    quad({0, 0, 0}, {0, 0, S}, {S, 0, S}, {S, 0, 0}, 0);  // floor (+y)
    quad({0, S, 0}, {S, S, 0}, {S, S, S}, {0, S, S}, 0);  // ceiling (-y)
    quad({0, 0, 0}, {S, 0, 0}, {S, S, 0}, {0, S, 0}, 0);  // z = 0 (+z)
    quad({0, 0, S}, {0, S, S}, {S, S, S}, {S, 0, S}, 0);  // z = S (-z)
    quad({0, 0, 0}, {0, S, 0}, {0, S, S}, {0, 0, S}, 0);  // x = 0 (+x)
    quad({S, 0, 0}, {S, 0, S}, {S, S, S}, {S, S, 0}, 0);  // x = S (-x)
    const float y = 0.01f, lo = 0.7f, hi = 1.3f;
    quad({lo, y, lo}, {lo, y, hi}, {hi, y, hi}, {hi, y, lo}, 1);  // the lamp (+y)
    Camera top;  // orthographic, straight down at the lamp's middle
    top.type = Camera::Type::Orthographic;
    top.position = glm::vec3(1.0f, 1.9f, 1.0f);
    top.worldFromCamera = glm::mat3(glm::vec3(1, 0, 0), glm::vec3(0, 0, -1), glm::vec3(0, 1, 0));
    top.xmag = top.ymag = 0.2f;
    scene.cameras.push_back(top);
    scene.updateBounds();
    return scene;
}

// No seams: on random points of every face shared by two occupied voxels of a baked Cornell box, the blended
// result just below and just above the face agrees to float precision, from every kernel; without blending
// the same faces jump (what the test would catch). Shading a black surface stays finite.
TEST(Bake, BlendedAssetIsContinuousAcrossEveryVoxelFace) {
    Scene scene = loadGltf(test::sourcePath("scenes/cornell-box/cornell-box.gltf"));
    BakeSettings s = smallSettings();
    s.grid = glm::uvec3(3);
    s.samples.points = 3000;
    s.samples.paths = 8;
    s.train.epochs = 60;
    double worstBlended = 0.0, worstPlain = 0.0;
    for (float band : {0.125f, 0.0f}) {
        s.blendBand = band;
        BakeResult r = bakeScene(scene, s);
        std::vector<uint8_t> bytes = format::encode(r.asset);
        nrad::Asset asset;
        ASSERT_EQ(asset.loadFromMemory(bytes.data(), bytes.size()), NRAD_OK);
        const format::Grid& g = r.asset.grid;
        std::vector<bool> occupied(g.voxelCount(), false);
        for (const format::VoxelEntry& v : r.asset.voxels) occupied[v.index] = true;
        SplitMix64 rng(11);
        std::vector<float> p, n, d;
        size_t faces = 0;
        for (uint32_t v = 0; v < g.voxelCount(); ++v) {
            const uint32_t c[3] = {v % g.dims[0], (v / g.dims[0]) % g.dims[1], v / (g.dims[0] * g.dims[1])};
            for (int axis = 0; axis < 3; ++axis) {
                if (c[axis] + 1 >= g.dims[axis]) continue;
                const uint32_t stride = axis == 0 ? 1 : axis == 1 ? g.dims[0] : g.dims[0] * g.dims[1];
                if (!occupied[v] || !occupied[v + stride]) continue;
                ++faces;
                for (int i = 0; i < 50; ++i) {
                    glm::vec3 q, nn, dd;
                    for (int k = 0; k < 3; ++k) {
                        const float size = (g.upper[k] - g.lower[k]) / float(g.dims[k]);
                        q[k] = g.lower[k] + size * (float(c[k]) + (k == axis ? 1.0f : rng.uniform()));
                    }
                    nn = glm::normalize(glm::vec3(rng.uniform(), rng.uniform(), rng.uniform()) - 0.5f + glm::vec3(0, 1e-3f, 0));
                    dd = glm::normalize(glm::vec3(rng.uniform(), rng.uniform(), rng.uniform()) - 0.5f + glm::vec3(1e-3f, 0, 0));
                    // The face's coordinate and the floats just below and above it: two voxels by the format's rule.
                    for (float side : {-1.0f, 1.0f}) {
                        glm::vec3 at = q;
                        at[axis] = std::nextafter(q[axis], q[axis] + side);
                        for (int k = 0; k < 3; ++k) {
                            p.push_back(at[k]);
                            n.push_back(nn[k]);
                            d.push_back(dd[k]);
                        }
                    }
                }
            }
        }
        ASSERT_GT(faces, 20u);
        const size_t count = p.size() / 3;
        for (NradKernel k : {NRAD_KERNEL_SCALAR, NRAD_KERNEL_AVX2, NRAD_KERNEL_AVX512}) {
            if (!nradKernelSupported(k)) continue;
            ASSERT_EQ(nradSelectKernel(k), NRAD_OK);
            std::vector<float> rgb(3 * count);
            std::vector<uint8_t> flags(count);
            ASSERT_EQ(asset.evaluateBatch(count, p.data(), n.data(), d.data(), rgb.data(), flags.data()), NRAD_OK);
            for (size_t j = 0; j < count; j += 2) {
                ASSERT_EQ(flags[j], NRAD_POINT_OK);
                ASSERT_EQ(flags[j + 1], NRAD_POINT_OK);
                for (int c = 0; c < 3; ++c) {
                    const double a = rgb[3 * j + size_t(c)], b = rgb[3 * (j + 1) + size_t(c)];
                    const double rel = std::abs(a - b) / std::max(0.5 * (a + b), 1e-3);
                    (band > 0.0f ? worstBlended : worstPlain) = std::max(band > 0.0f ? worstBlended : worstPlain, rel);
                }
            }
            // Zero albedo: the demodulated asset shaded on a black surface is finite (it is the emission, 0).
            std::vector<NradSurface> black(count);
            for (NradSurface& m : black) {
                m = NradSurface{};
                m.roughness = 1.0f;
                m.specular = 0.0f;
            }
            std::vector<float> shaded(3 * count, -1.0f);
            ASSERT_EQ(nradShadeBatch(asset.get(), count, p.data(), n.data(), d.data(), black.data(), shaded.data(), nullptr), NRAD_OK);
            for (float x : shaded) ASSERT_TRUE(std::isfinite(x) && x >= 0.0f && x < 1e-6f) << x;
        }
        nradSelectKernel(NRAD_KERNEL_AUTO);
    }
    std::printf("worst relative jump across faces: blended %.3g, unblended %.3g\n", worstBlended, worstPlain);
    EXPECT_LT(worstBlended, 1e-4);  // float precision of a network evaluated one float apart
    EXPECT_GT(worstPlain, 1e-2);  // independent networks meet with a step
}

TEST(Bake, EmissionStaysOutOfTheNetworks) {
    Scene scene = lampInAnEmptyRoom();
    BakeSettings s = smallSettings();
    s.grid = glm::uvec3(2);
    s.train.demodulate = false;  // the raw scattered radiance, to look at it (demodulated below)
    BakeResult r = bakeScene(scene, s);
    EXPECT_EQ(r.asset.header.flags, format::kFlagScatteredRadiance | format::kFlagBlended);
    EXPECT_EQ(r.asset.grid.blendBand, s.blendBand);
    std::vector<uint8_t> bytes = format::encode(r.asset);
    nrad::Asset asset;
    ASSERT_EQ(asset.loadFromMemory(bytes.data(), bytes.size()), NRAD_OK);
    NradAssetInfo info;
    ASSERT_EQ(nradGetAssetInfo(asset.get(), &info), NRAD_OK);
    EXPECT_EQ(info.contentFlags, NRAD_CONTENT_SCATTERED_RADIANCE | NRAD_CONTENT_BLENDED);
    EXPECT_EQ(info.blendBand, s.blendBand);
    // On the lamp, towards many directions: the asset's scattered radiance is ~0 (the floor around it,
    // in the same voxels, is lit to about 0.02).
    double onLamp = 0.0, onFloor = 0.0;
    int n = 0;
    for (int i = 0; i < 16; ++i)
        for (int j = 0; j < 16; ++j) {
            float p[3] = {0.72f + 0.56f * float(i) / 15.0f, 0.01f, 0.72f + 0.56f * float(j) / 15.0f};
            float q[3] = {0.2f + 0.1f * float(i) / 15.0f, 0.0f, 0.2f + 0.1f * float(j) / 15.0f};
            glm::vec3 d = glm::normalize(glm::vec3(std::sin(float(i + 16 * j)), 1.5f, std::cos(float(3 * i + j))));
            float nrm[3] = {0, 1, 0}, dir[3] = {d.x, d.y, d.z}, rgb[3];
            ASSERT_EQ(asset.evaluate(p, nrm, dir, rgb), NRAD_OK);
            onLamp += (rgb[0] + rgb[1] + rgb[2]) / 3.0;
            ASSERT_EQ(asset.evaluate(q, nrm, dir, rgb), NRAD_OK);
            onFloor += (rgb[0] + rgb[1] + rgb[2]) / 3.0;
            ++n;
        }
    onLamp /= n;
    onFloor /= n;
    EXPECT_GT(onFloor, 0.01);
    EXPECT_LT(onLamp, 0.01 * 3.0) << "floor " << onFloor;  // 1% of the lamp's mean emission
    std::printf("asset on the lamp %.5f, on the floor beside it %.5f\n", onLamp, onFloor);
    // Rendered through the asset, the lamp is its emission (scattered ~0 plus Le from the material).
    Accel accel(scene);
    RenderSettings rs;
    rs.width = rs.height = 16;
    rs.spp = 1;
    Image image;
    ASSERT_EQ(renderThroughAsset(scene, accel, asset.get(), scene.cameras[0], rs, image), NRAD_OK);
    glm::vec3 mean = image.mean();
    EXPECT_NEAR(mean.x, 5.0f, 0.1f);
    EXPECT_NEAR(mean.y, 3.0f, 0.1f);
    EXPECT_NEAR(mean.z, 1.0f, 0.1f);
    // Demodulated (the default): the black lamp's reflectance is 0, so whatever its network holds, the shaded
    // lamp (nradShadeBatch, as an engine calls it) is exactly its emission.
    s.train.demodulate = true;
    BakeResult d = bakeScene(scene, s);
    EXPECT_EQ(d.asset.header.flags, format::kFlagScatteredRadiance | format::kFlagDemodulated | format::kFlagBlended);
    bytes = format::encode(d.asset);
    nrad::Asset demod;
    ASSERT_EQ(demod.loadFromMemory(bytes.data(), bytes.size()), NRAD_OK);
    std::vector<float> p, nrm, dir;
    std::vector<NradSurface> surfaces;
    for (int i = 0; i < 64; ++i) {
        const float pt[3] = {0.72f + 0.56f * float(i % 8) / 7.0f, 0.01f, 0.72f + 0.56f * float(i / 8) / 7.0f};
        glm::vec3 w = glm::normalize(glm::vec3(std::sin(float(i)), 1.2f, std::cos(float(i))));
        for (int k = 0; k < 3; ++k) {
            p.push_back(pt[k]);
            nrm.push_back(k == 1 ? 1.0f : 0.0f);
            dir.push_back(w[k]);
        }
        surfaces.push_back(NradSurface{{0.0f, 0.0f, 0.0f}, 0.0f, 1.0f, 0.0f, {5.0f, 3.0f, 1.0f}});
    }
    std::vector<float> shaded(p.size());
    ASSERT_EQ(nradShadeBatch(demod.get(), 64, p.data(), nrm.data(), dir.data(), surfaces.data(), shaded.data(), nullptr), NRAD_OK);
    for (int i = 0; i < 64; ++i) {
        EXPECT_EQ(shaded[size_t(3 * i)], 5.0f);
        EXPECT_EQ(shaded[size_t(3 * i + 1)], 3.0f);
        EXPECT_EQ(shaded[size_t(3 * i + 2)], 1.0f);
    }
    ASSERT_EQ(renderThroughAsset(scene, accel, demod.get(), scene.cameras[0], rs, image), NRAD_OK);
    EXPECT_NEAR(image.mean().x, 5.0f, 1e-4f);
}

TEST(Bake, DemodulatedNetworksLearnLightingAndTheTextureStaysSharp) {
    // A Lambertian plane with an 8 x 8 checker base-colour texture (0.2 / 0.8) under a sun of irradiance 3
    // from straight above: the scattered radiance is albedo(x) 3 / pi, its demodulated value 3 / pi everywhere.
    // The networks must hold that texture-free term, and the shaded result the texture, texel for texel.
    Scene scene = test::makeLitPlane(1.0f, 1.0f);
    Texture checker;
    checker.width = checker.height = 8;
    for (int y = 0; y < 8; ++y)
        for (int x = 0; x < 8; ++x) checker.texels.push_back(glm::vec4(glm::vec3((x + y) % 2 ? 0.8f : 0.2f), 1.0f));
    checker.wrapS = checker.wrapT = WrapMode::ClampToEdge;
    checker.computeAverage();
    scene.textures.push_back(checker);
    scene.materials[0].baseColorTexture.texture = 0;
    const glm::vec2 uv[4] = {{0, 1}, {1, 1}, {1, 0}, {0, 0}};  // the plane's corners (-1,-1), (1,-1), (1,1), (-1,1)
    for (int i = 0; i < 4; ++i) scene.mesh.uv0[size_t(i)] = uv[i];
    PunctualLight sun;
    sun.type = PunctualLight::Type::Directional;
    sun.direction = glm::vec3(0, 0, -1);
    sun.intensity = glm::vec3(3.0f);
    scene.lights.push_back(sun);
    BakeSettings s = smallSettings();
    s.grid = glm::uvec3(2, 2, 1);
    BakeResult r = bakeScene(scene, s);
    ASSERT_EQ(r.asset.header.flags, format::kFlagScatteredRadiance | format::kFlagDemodulated | format::kFlagBlended);
    std::vector<uint8_t> bytes = format::encode(r.asset);
    nrad::Asset asset;
    ASSERT_EQ(asset.loadFromMemory(bytes.data(), bytes.size()), NRAD_OK);
    const float irradianceTerm = 3.0f / 3.14159265f;
    std::vector<float> p, n, d;
    std::vector<NradSurface> surfaces;
    std::vector<float> albedo;
    for (int i = 0; i < 400; ++i) {
        // Texel centres (away from the bilinear blend at texel borders), random view directions.
        int tx = i % 8, ty = (i / 8) % 8;
        float x = -1.0f + (float(tx) + 0.5f) / 4.0f, y = 1.0f - (float(ty) + 0.5f) / 4.0f;
        glm::vec3 w = glm::normalize(glm::vec3(std::sin(1.7f * float(i)), std::cos(2.3f * float(i)), 1.5f));
        const float a = (tx + ty) % 2 ? 0.8f : 0.2f;
        for (int k = 0; k < 3; ++k) {
            p.push_back(k == 0 ? x : k == 1 ? y : 0.0f);
            n.push_back(k == 2 ? 1.0f : 0.0f);
            d.push_back(w[k]);
        }
        surfaces.push_back(NradSurface{{a, a, a}, 0.0f, 1.0f, 0.0f, {0.0f, 0.0f, 0.0f}});
        albedo.push_back(a);
    }
    std::vector<float> raw(p.size()), shaded(p.size());
    ASSERT_EQ(asset.evaluateBatch(400, p.data(), n.data(), d.data(), raw.data(), nullptr), NRAD_OK);
    ASSERT_EQ(nradShadeBatch(asset.get(), 400, p.data(), n.data(), d.data(), surfaces.data(), shaded.data(), nullptr), NRAD_OK);
    double worstRaw = 0.0, worstShaded = 0.0;
    for (int i = 0; i < 400; ++i)
        for (int c = 0; c < 3; ++c) {
            worstRaw = std::max(worstRaw, std::abs(double(raw[size_t(3 * i + c)]) / irradianceTerm - 1.0));
            worstShaded = std::max(worstShaded, std::abs(double(shaded[size_t(3 * i + c)]) / (albedo[size_t(i)] * irradianceTerm) - 1.0));
        }
    std::printf("demodulated checker plane: worst relative error of the network's term %.4f, of the shaded texel %.4f\n",
                worstRaw, worstShaded);
    // Stated bound (docs/training.md): 1% everywhere, for the lighting term and for every texel (measured
    // 0.09%; a network that had to learn the checker itself is off by tens of percent at its edges).
    EXPECT_LT(worstRaw, 0.01);
    EXPECT_LT(worstShaded, 0.01);
}

// A lid (single-sided, facing up) 1 mm above the middle quarter of a lit plane: the plane under it is
// hidden from every viewer above, as the floor under a box or the ceiling behind a light panel is.
Scene planeWithALid(bool lidDoubleSided) {
    Scene scene = test::makeLitPlane(0.5f, 1.0f);
    Material lid = scene.materials[0];
    lid.doubleSided = lidDoubleSided;
    scene.materials.push_back(lid);
    TriangleMesh& mesh = scene.mesh;
    const uint32_t base = uint32_t(mesh.positions.size());
    for (glm::vec2 c : {glm::vec2(-1, -1), glm::vec2(1, -1), glm::vec2(1, 1), glm::vec2(-1, 1)}) {
        mesh.positions.emplace_back(0.5f * c.x, 0.5f * c.y, 0.001f);
        mesh.normals.emplace_back(0, 0, 1);
        mesh.uv0.emplace_back(0.0f);
        mesh.uv1.emplace_back(0.0f);
    }
    mesh.triangles.push_back({base, base + 1, base + 2});
    mesh.triangles.push_back({base, base + 2, base + 3});
    mesh.materialIds.push_back(1);
    mesh.materialIds.push_back(1);
    scene.lights.push_back(directionalSun(glm::vec3(0, 0, -1), glm::vec3(3.0f)));
    scene.updateBounds();
    return scene;
}

TEST(Bake, PointsNoViewerSeesAreNotTrained) {
    Scene scene = planeWithALid(false);
    Accel accel(scene);
    LightSampler lights(scene);
    PathTracer tracer(scene, accel, lights);
    auto viewable = [&](glm::vec3 p, glm::vec3 wo, const Scene& sc, const PathTracer& t) {
        Hit hit;
        hit.triangle = p.z > 0.0005f ? 2u : 0u;
        SurfaceInteraction si = makeInteraction(sc, hit, -glm::normalize(wo));
        si.p = p;
        return t.viewable(si);
    };
    // Under the lid: hidden, straight up and obliquely; beside it, or grazing out from under its edge: seen.
    EXPECT_FALSE(viewable({0.0f, 0.0f, 0.0f}, {0, 0, 1}, scene, tracer));
    EXPECT_FALSE(viewable({0.4f, 0.1f, 0.0f}, {0.3f, -0.2f, 1.0f}, scene, tracer));
    EXPECT_TRUE(viewable({0.8f, 0.0f, 0.0f}, {0, 0, 1}, scene, tracer));
    EXPECT_TRUE(viewable({0.4999f, 0.0f, 0.0f}, {1.0f, 0.0f, 0.01f}, scene, tracer));
    EXPECT_TRUE(viewable({0.0f, 0.0f, 0.001f}, {0, 0, 1}, scene, tracer));  // the lid's own top
    // A double-sided lid may be seen from below: nothing is hidden.
    Scene twoSided = planeWithALid(true);
    Accel accel2(twoSided);
    LightSampler lights2(twoSided);
    PathTracer tracer2(twoSided, accel2, lights2);
    EXPECT_TRUE(viewable({0.0f, 0.0f, 0.0f}, {0, 0, 1}, twoSided, tracer2));
    // Nor a lid one sees through (a window pane's back, say).
    Scene glass = planeWithALid(false);
    glass.materials[1].transmission = 1.0f;
    Accel accel3(glass);
    LightSampler lights3(glass);
    PathTracer tracer3(glass, accel3, lights3);
    EXPECT_TRUE(viewable({0.0f, 0.0f, 0.0f}, {0, 0, 1}, glass, tracer3));

    // The bake drops the hidden points: the plane under the lid is a fifth of the surface (1 of 5 m^2).
    BakeSettings s = smallSettings();
    s.grid = glm::uvec3(2, 2, 1);
    BakeResult r = bakeScene(scene, s);
    const double hiddenShare = double(r.sampleStats.hiddenSamples) / double(r.sampleStats.points + r.sampleStats.floorPoints);
    EXPECT_NEAR(hiddenShare, 0.2, 0.01);
    EXPECT_EQ(r.sampleCount + r.sampleStats.hiddenSamples, r.sampleStats.points + r.sampleStats.floorPoints);
    // What the networks then learn beside the lid is the lit plane's closed form, a E / pi (demodulated:
    // E / pi, with no indirect light: the lid's top and the plane see only the sky, which is black); with the
    // hidden points kept, each network must also draw the dark plane under the lid in the same voxel.
    BakeSettings keep = s;
    keep.samples.dropHidden = false;
    BakeResult k = bakeScene(scene, keep);
    EXPECT_EQ(k.sampleStats.hiddenSamples, 0u);
    auto rmsBeside = [&](const BakeResult& b) {
        std::vector<uint8_t> bytes = format::encode(b.asset);
        nrad::Asset asset;
        EXPECT_EQ(asset.loadFromMemory(bytes.data(), bytes.size()), NRAD_OK);
        double sq = 0.0;
        for (int i = 0; i < 200; ++i) {
            // A ring 1 to 20 cm outside the lid's edge, on all four sides.
            const float t = -0.5f + float(i % 50) / 49.0f, off = 0.51f + 0.19f * float((i * 7) % 11) / 10.0f;
            const int side = i / 50;
            float p[3] = {side < 2 ? (side == 0 ? off : -off) : t, side < 2 ? t : (side == 2 ? off : -off), 0.0f};
            glm::vec3 w = glm::normalize(glm::vec3(std::sin(1.3f * float(i)), std::cos(0.7f * float(i)), 1.2f));
            float n[3] = {0, 0, 1}, d[3] = {w.x, w.y, w.z}, rgb[3];
            EXPECT_EQ(asset.evaluate(p, n, d, rgb), NRAD_OK);
            for (int c = 0; c < 3; ++c) sq += std::pow(double(rgb[c]) / (3.0 / 3.14159265) - 1.0, 2);
        }
        return std::sqrt(sq / 600.0);
    };
    const double dropped = rmsBeside(r), kept = rmsBeside(k);
    std::printf("plane beside a lid: rms relative error %.4f with hidden points dropped, %.4f with them kept\n", dropped, kept);
    // Stated bounds: 5% rms (measured 0.5-2.5% over six training schedules, with and without the parameters' epoch
    // average: the fit of a small network to a constant beside the lid's shadow edge), against tens of percent
    // when each network must also draw the dark plane under the lid (measured 31%). The worst point of the ring,
    // the figure this test read before, moved between 1.1% and 11.8% with the schedule alone.
    EXPECT_LT(dropped, 0.05);
    EXPECT_GT(kept, 0.2);
}

}  // namespace
}  // namespace nrad

namespace nrad {
namespace {

// Mixed lighting: a sun the engine draws itself leaves only its indirect light in the asset. On a lone
// Lambertian plane there is none, so the networks hold ~0, and rendering through the asset (which adds the
// engine-drawn sun's direct light exactly, with a shadow ray) gives the closed form (a / pi) E cos.
TEST(Bake, EngineDrawnSunLeavesOnlyIndirectLightInTheAsset) {
    Scene scene = test::makeLitPlane(0.5f, 1.0f);
    PunctualLight sun = directionalSun(-glm::vec3(0.3f, 0.2f, 1.0f), glm::vec3(2.0f, 1.0f, 0.5f));
    sun.name = "sun";
    sun.runtimeDirect = true;
    scene.lights.push_back(sun);
    scene.updateBounds();
    BakeSettings s = smallSettings();
    s.grid = glm::uvec3(2, 2, 1);
    s.samples.points = 1000;
    s.samples.paths = 4;
    BakeResult r = bakeScene(scene, s);
    EXPECT_NE(assetMetadata(scene, s, r).find("\"engine_drawn_direct\":[{\"light\":0,\"name\":\"sun\"}]"), std::string::npos);
    std::vector<uint8_t> bytes = format::encode(r.asset);
    nrad::Asset asset;
    ASSERT_EQ(asset.loadFromMemory(bytes.data(), bytes.size()), NRAD_OK);
    const float cosSun = glm::dot(-sun.direction, glm::vec3(0, 0, 1));
    const glm::vec3 direct = 0.5f / 3.14159265f * sun.intensity * cosSun;
    for (int i = 0; i < 16; ++i) {
        float p[3] = {-0.9f + 0.12f * float(i), 0.3f - 0.04f * float(i), 0.0f}, n[3] = {0, 0, 1}, d[3] = {0, 0, 1}, rgb[3];
        ASSERT_EQ(asset.evaluate(p, n, d, rgb), NRAD_OK);
        for (int c = 0; c < 3; ++c) EXPECT_LT(rgb[c], 1e-3f * direct.x) << i;  // no indirect light to learn
    }
    Accel accel(scene);
    RenderSettings rs;
    rs.width = rs.height = 8;
    rs.spp = 1;
    Image image;
    ASSERT_EQ(renderThroughAsset(scene, accel, asset.get(), scene.cameras[0], rs, image), NRAD_OK);
    for (int c = 0; c < 3; ++c) EXPECT_NEAR(image.mean()[c] / direct[c], 1.0, 1e-3) << c;
    // The same sun baked into the asset: the networks learn the direct light.
    scene.lights[0].runtimeDirect = false;
    BakeResult all = bakeScene(scene, s);
    bytes = format::encode(all.asset);
    nrad::Asset baked;
    ASSERT_EQ(baked.loadFromMemory(bytes.data(), bytes.size()), NRAD_OK);
    ASSERT_EQ(renderThroughAsset(scene, accel, baked.get(), scene.cameras[0], rs, image), NRAD_OK);
    for (int c = 0; c < 3; ++c) EXPECT_NEAR(image.mean()[c] / direct[c], 1.0, 0.05) << c;
}

// Byte-identical assets for one and two threads under an environment map and a soft sun (the sampler's
// distribution, escaped rays and the disk's cone are all per-sample deterministic).
TEST(Bake, ByteIdenticalForOneAndTwoThreadsUnderAnEnvironmentMap) {
    Scene scene = test::makeLitPlane(0.6f, 1.0f);
    scene.environment.kind = Environment::Kind::Map;
    scene.environment.width = 16;
    scene.environment.height = 8;
    for (int i = 0; i < 128; ++i) scene.environment.texels.push_back(glm::vec3(0.1f + 0.05f * float(i % 7), 0.2f, 0.05f * float(i % 5)));
    scene.environment.texels[37] = glm::vec3(400.0f);
    scene.environment.rotationDegrees = 33.0f;
    PunctualLight sun;
    sun.type = PunctualLight::Type::Directional;
    sun.direction = glm::normalize(glm::vec3(-0.2f, -1.0f, 0.1f));
    sun.intensity = glm::vec3(3.0f);
    sun.cosAngularRadius = 0.999f;
    scene.lights.push_back(sun);
    BakeSettings s = smallSettings();
    s.grid = glm::uvec3(2, 2, 1);
    s.samples.points = 800;
    s.samples.paths = 8;
    const std::vector<uint8_t> one = test::bakeBytes(scene, s, 1);
    EXPECT_EQ(test::bakeBytes(scene, s, 2), one);
    scene.environment.rotationDegrees = 34.0f;  // the map is really used
    EXPECT_NE(format::encode(bakeScene(scene, s).asset), one);
}

// Training within the integral equation (paper Sec. 3): the settings of a small integral bake.
BakeSettings integralSettings(BakeSettings s) {
    s.training = TrainingMethod::Integral;
    s.samples.paths = 4;
    s.integral.generations = 4;
    s.integral.points = 6000;
    return s;
}

// Byte-identical for one and two threads: each round's targets come from the networks frozen before it, and
// every network trains on its own samples in a fixed order.
TEST(Bake, IntegralTrainingIsByteIdenticalForOneAndTwoThreads) {
    Scene scene = loadGltf(test::sourcePath("scenes/cornell-box-glossy/cornell-box-glossy.gltf"));
    BakeSettings s = integralSettings(smallSettings());
    s.grid = glm::uvec3(3);
    s.samples.points = 1500;
    const std::vector<uint8_t> one = test::bakeBytes(scene, s, 1);
    EXPECT_EQ(test::bakeBytes(scene, s, 2), one);
    BakeResult r = bakeScene(scene, s);
    ASSERT_EQ(r.generations.size(), 5u);  // the start and four rounds
    for (const GenerationStats& g : r.generations) EXPECT_GT(g.samples, 5000u * (g.generation > 0));
    EXPECT_NE(assetMetadata(scene, s, r).find("\"method\":\"integral\""), std::string::npos);
    s.integral.generations = 3;  // the rounds really change the networks
    EXPECT_NE(test::bakeBytes(scene, s, 2), one);
}

// One bounce of light (a Lambertian plane under a sun, nothing else): what the networks learn is the sun's
// direct light (a / pi) E cos, which both methods estimate exactly but for noise; the assets agree with it
// and with each other within 1%.
TEST(Bake, IntegralAndMonteCarloTrainingAgreeOnOneBounceOfLight) {
    Scene scene = test::makeLitPlane(0.5f, 1.0f);
    const PunctualLight sun = directionalSun(-glm::vec3(0.3f, 0.2f, 1.0f), glm::vec3(2.0f, 1.0f, 0.5f));
    scene.lights.push_back(sun);
    scene.updateBounds();
    BakeSettings mc = smallSettings();
    mc.grid = glm::uvec3(2, 2, 1);
    mc.samples.points = 2000;
    mc.samples.paths = 8;
    BakeSettings in = integralSettings(mc);
    in.samples.points = 500;  // a poor start, which the rounds have to correct
    in.samples.paths = 1;
    nrad::Asset assets[2];
    std::vector<uint8_t> bytes[2];
    for (int k = 0; k < 2; ++k) {
        bytes[k] = format::encode(bakeScene(scene, k == 0 ? mc : in).asset);
        ASSERT_EQ(assets[k].loadFromMemory(bytes[k].data(), bytes[k].size()), NRAD_OK);
    }
    const glm::vec3 direct = 0.5f / 3.14159265f * sun.intensity * glm::dot(-sun.direction, glm::vec3(0, 0, 1));
    double worst = 0.0, worstBetween = 0.0;
    for (int i = 0; i < 64; ++i) {
        const float p[3] = {-0.9f + 0.028f * float(i), 0.8f - 0.025f * float(i), 0.0f}, n[3] = {0, 0, 1};
        const glm::vec3 d = glm::normalize(glm::vec3(0.4f * std::sin(float(i)), 0.4f * std::cos(float(i)), 1.0f));
        float rgb[2][3];
        for (int k = 0; k < 2; ++k) ASSERT_EQ(assets[k].evaluate(p, n, &d.x, rgb[k]), NRAD_OK);
        for (int c = 0; c < 3; ++c) {
            // Demodulated: the asset holds radiance / reflectance; the plane's reflectance is its albedo here
            // up to the specular-free lobe's terms, so compare the two assets directly and each with the
            // closed form through the contract's reflectance.
            eval::Surface surface;
            for (float& b : surface.baseColor) b = 0.5f;
            surface.specular = 0.0f;
            float shaded[2][3];
            for (int k = 0; k < 2; ++k) eval::shade(format::kFlagScatteredRadiance | format::kFlagDemodulated, rgb[k], surface, d.z, shaded[k]);
            for (int k = 0; k < 2; ++k) worst = std::max(worst, std::abs(double(shaded[k][c]) / direct[c] - 1.0));
            worstBetween = std::max(worstBetween, std::abs(double(shaded[1][c]) / double(shaded[0][c]) - 1.0));
        }
    }
    std::printf("one bounce of light: worst relative error %.4f against the closed form, %.4f between the methods\n", worst, worstBetween);
    EXPECT_LT(worst, 0.01);  // measured 0.0027
    EXPECT_LT(worstBetween, 0.01);
}

}  // namespace
}  // namespace nrad
