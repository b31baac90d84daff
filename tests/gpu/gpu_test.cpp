// The GLSL shading path (runtime/shaders) against the CPU runtime, on a real Vulkan device (lavapipe in CI):
// random batches through every kind of asset (grid and kd-tree, blended or not, both output transforms,
// other topologies, fp32 weights), and whole G-buffers of every bundled scene's baked asset, evaluated and
// shaded. Label `gpu`. Without a Vulkan device the tests skip with the reason; NRAD_REQUIRE_VULKAN=1 (set
// by ./run.sh, which installs lavapipe) turns that into a failure, so CI can never pass them by skipping.
#include <nrad/eval.h>
#include <nrad/format.h>
#include <nrad/nrad.h>
#include <nrad/nrad.hpp>

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <cstring>
#include <limits>
#include <fstream>
#include <random>

#include <gtest/gtest.h>

#include "baker/bake/baker.h"
#include "baker/render/accel.h"
#include "baker/render/camera.h"
#include "baker/render/surface.h"
#include "baker/render/image_io.h"
#include "baker/scene/gltf_loader.h"
#include "baker/validate/metrics.h"
#include "gpu/gbuffer.h"
#include "gpu/vulkan_compute.h"
#include "support/random_asset.h"
#include "support/shade_reference.h"
#include "support/test_paths.h"
#include "support/test_trees.h"

namespace nrad {
namespace {

// What the GPU may differ from the CPU runtime by (docs/runtime.md, "GPU buffers"): relative to the larger of
// the CPU's value and kAbsoluteFloor x the batch's largest value. fp16 weights are the same on both sides;
// what differs is the order of sums, fused multiply-adds and the GPU's division and exp2.
constexpr double kRelativeTolerance = 2e-4;
constexpr double kAbsoluteFloor = 1e-3;

gpu::VulkanCompute* context() {
    static std::string why;
    static std::unique_ptr<gpu::VulkanCompute> c = gpu::VulkanCompute::create(why);
    if (!c) {
        const char* require = std::getenv("NRAD_REQUIRE_VULKAN");
        if (require && std::string(require) == "1") ADD_FAILURE() << "NRAD_REQUIRE_VULKAN=1 but no Vulkan device: " << why;
        return nullptr;
    }
    return c.get();
}

#define NRAD_NEED_VULKAN()                                                                                              \
    gpu::VulkanCompute* vk = context();                                                                                \
    if (!vk) GTEST_SKIP() << "no Vulkan device (install mesa-vulkan-drivers for lavapipe): the GPU path is not tested here"

struct Result {
    std::vector<float> rgb;
    std::vector<uint32_t> flags;
};

// Evaluates (shade = false) or shades the points with the compute shader (volume: the light in the volume).
// spv: the compute shader, nrad_evaluate.comp (GLSL) or nrad_evaluate.hlsl (HLSL) compiled.
Result runOnGpu(gpu::VulkanCompute& vk, const nrad::Asset& asset, const GBuffer& g, bool shade, double* ms = nullptr,
                bool volume = false, const char* spv = NRAD_EVALUATE_SPV) {
    size_t bytes = 0;
    EXPECT_EQ(nradGetGpuBufferSize(asset.get(), &bytes), NRAD_OK);
    std::vector<uint32_t> packed(bytes / 4);
    EXPECT_EQ(nradPackGpuBuffer(asset.get(), packed.data(), bytes), NRAD_OK);
    const size_t n = g.count();
    gpu::VulkanCompute::Pipeline* p = vk.pipeline(spv, 7, 8);
    std::vector<gpu::VulkanCompute::Buffer*> b = {vk.buffer(bytes), vk.buffer(12 * n), vk.buffer(12 * n), vk.buffer(12 * n),
                                                  vk.buffer(sizeof(NradSurface) * n), vk.buffer(12 * n), vk.buffer(4 * n)};
    vk.upload(b[0], packed.data(), bytes);
    vk.upload(b[1], g.positions.data(), 12 * n);
    vk.upload(b[2], g.normals.data(), 12 * n);
    vk.upload(b[3], g.directions.data(), 12 * n);
    if (shade) vk.upload(b[4], g.surfaces.data(), sizeof(NradSurface) * n);
    const uint32_t push[2] = {uint32_t(n), (shade ? 1u : 0u) | (volume ? 2u : 0u)};
    const double t = vk.dispatch(p, b, push, uint32_t((n + 63) / 64));
    if (ms) *ms = t;
    Result r;
    r.rgb.resize(3 * n);
    r.flags.resize(n);
    vk.download(b[5], r.rgb.data(), 12 * n);
    vk.download(b[6], r.flags.data(), 4 * n);
    return r;
}

Result runOnCpu(const nrad::Asset& asset, const GBuffer& g, bool shade) {
    const size_t n = g.count();
    Result r;
    r.rgb.resize(3 * n);
    std::vector<uint8_t> f(n);
    if (shade)
        EXPECT_EQ(nradShadeBatch(asset.get(), n, g.positions.data(), g.normals.data(), g.directions.data(), g.surfaces.data(),
                                 r.rgb.data(), f.data()),
                  NRAD_OK);
    else
        EXPECT_EQ(asset.evaluateBatch(n, g.positions.data(), g.normals.data(), g.directions.data(), r.rgb.data(), f.data()),
                  NRAD_OK);
    r.flags.assign(f.begin(), f.end());
    return r;
}

// The light in the volume on the CPU: nradEvaluateVolumeBatch, shaded by eval::shadeVolume as nradShadeGBuffer does.
Result runVolumeOnCpu(const nrad::Asset& asset, const GBuffer& g, bool shade) {
    const size_t n = g.count();
    Result r;
    r.rgb.resize(3 * n);
    std::vector<uint8_t> f(n);
    EXPECT_EQ(nradEvaluateVolumeBatch(asset.get(), n, g.positions.data(), g.normals.data(), r.rgb.data(), f.data()), NRAD_OK);
    if (shade) test::shadeReference(0, n, g.normals.data(), g.directions.data(), g.surfaces.data(), r.rgb.data(), true);
    r.flags.assign(f.begin(), f.end());
    return r;
}

struct Agreement {
    double worst = 0.0;  // the largest difference relative to max(|cpu|, floor)
    size_t flagMismatches = 0, nonFinite = 0;
};

Agreement compare(const Result& gpu, const Result& cpu) {
    Agreement a;
    float largest = 0.0f;
    for (float v : cpu.rgb) largest = std::max(largest, std::abs(v));
    const double floor = std::max(kAbsoluteFloor * double(largest), 1e-30);
    for (size_t i = 0; i < cpu.flags.size(); ++i) a.flagMismatches += gpu.flags[i] != cpu.flags[i];
    for (size_t i = 0; i < cpu.rgb.size(); ++i) {
        if (!std::isfinite(gpu.rgb[i])) {
            ++a.nonFinite;
            continue;
        }
        a.worst = std::max(a.worst, std::abs(double(gpu.rgb[i]) - double(cpu.rgb[i])) / std::max(std::abs(double(cpu.rgb[i])), floor));
    }
    return a;
}

// Random points, most inside randomAsset's grid, with random surfaces; some with non-finite inputs.
GBuffer randomPoints(size_t count, uint32_t seed) {
    std::mt19937 rng(seed);
    std::uniform_real_distribution<float> u(-1.0f, 1.0f), u01(0.0f, 1.0f);
    GBuffer g;
    for (size_t i = 0; i < count; ++i) {
        glm::vec3 p(u(rng) * 2.0f + 0.5f, u(rng) * 2.8f + 0.5f, u(rng) * 3.8f + 0.5f);
        glm::vec3 n = glm::normalize(glm::vec3(u(rng), u(rng), u(rng)) + glm::vec3(0, 0, 1e-3f));
        glm::vec3 d = glm::normalize(glm::vec3(u(rng), u(rng), u(rng)) + glm::vec3(1e-3f, 0, 0));
        if (i % 997 == 5) p.y = std::numeric_limits<float>::quiet_NaN();
        if (i % 991 == 7) d.x = std::numeric_limits<float>::infinity();
        NradSurface s{{u01(rng), u01(rng), u01(rng)}, u01(rng) < 0.3f ? 1.0f : 0.0f, u01(rng), 1.0f, {0, 0, 0}};
        if (i % 5 == 0) s.emission[0] = s.emission[1] = s.emission[2] = 4.0f * u01(rng);
        g.add(p, n, d, s);
    }
    return g;
}

// Turns a random grid asset into a kd-tree one: a random tree over a 16^3 lattice, a network in every other leaf
// (its weights resized, for the caller to fill). False if the tree is not valid.
bool makeTreeAsset(format::Asset& a) {
    for (int k = 0; k < 3; ++k) a.grid.dims[k] = 16;
    a.header.flags |= format::kFlagTree;
    a.tree = test::randomTree(a.grid.dims, 90, 8);
    uint32_t leaves = 0;
    if (!format::validateTree(a.grid.dims, a.tree, leaves)) return false;
    a.voxels.clear();
    for (uint32_t l = 0; l < leaves; l += 2) a.voxels.push_back({l, 0.5f + 0.1f * float(l)});
    a.weights.resize(a.voxels.size() * a.topology.parameterCount());
    return true;
}

nrad::Asset load(const format::Asset& a) {
    const std::vector<uint8_t> bytes = format::encode(a);
    nrad::Asset asset;
    EXPECT_EQ(asset.loadFromMemory(bytes.data(), bytes.size()), NRAD_OK);
    return asset;
}

TEST(Gpu, RandomBatchesMatchTheCpuRuntime) {
    NRAD_NEED_VULKAN();
    std::printf("Vulkan device: %s\n", vk->deviceName().c_str());
    const GBuffer points = randomPoints(20000, 3);
    struct Case {
        const char* name;
        std::vector<uint32_t> hidden;
        format::OutputTransform transform;
        float band;
        bool tree;
        bool extreme = false;  // the largest fp16 weights and float scales: outputs clamped at eval::kMaxRadiance
    };
    const std::vector<Case> cases = {
        {"grid, exponential", {9}, format::OutputTransform::Exponential, 0.0f, false},
        {"grid, blended", {9}, format::OutputTransform::Exponential, 0.125f, false},
        {"grid, linear, 16-8 hidden", {16, 8}, format::OutputTransform::ClampedLinear, 0.0625f, false},
        {"grid, 32 hidden (the GPU maximum)", {32}, format::OutputTransform::Exponential, 0.0f, false},
        {"tree", {9}, format::OutputTransform::Exponential, 0.0f, true},
        {"tree, blended", {9}, format::OutputTransform::Exponential, 0.125f, true},
        {"extreme weights and scales, linear", {9}, format::OutputTransform::ClampedLinear, 0.125f, false, true},
        {"extreme weights and scales, exp", {9}, format::OutputTransform::Exponential, 0.125f, false, true},
    };
    for (const Case& c : cases) {
        format::Asset a = test::randomAsset(c.hidden, format::WeightEncoding::Float16, c.transform, 11, glm::uvec3(4, 3, 5), c.band);
        if (c.tree) {
            ASSERT_TRUE(makeTreeAsset(a));
            std::mt19937 rng(5);
            std::uniform_real_distribution<float> u(-0.6f, 0.6f);
            for (float& w : a.weights) w = format::halfToFloat(format::floatToHalf(u(rng)));
        }
        if (c.extreme) {
            for (size_t i = 0; i < a.weights.size(); ++i) a.weights[i] = i % 3 == 0 ? -65504.0f : 65504.0f;
            for (format::VoxelEntry& v : a.voxels) v.scale = 3.0e38f;
        }
        a.header.flags |= format::kFlagScatteredRadiance | format::kFlagDemodulated;
        nrad::Asset asset = load(a);
        for (bool shade : {false, true}) {
            const Agreement r = compare(runOnGpu(*vk, asset, points, shade), runOnCpu(asset, points, shade));
            std::printf("%-36s %-8s worst relative difference %.3g\n", c.name, shade ? "shade" : "evaluate", r.worst);
            EXPECT_EQ(r.flagMismatches, 0u) << c.name;
            EXPECT_EQ(r.nonFinite, 0u) << c.name;
            EXPECT_LE(r.worst, kRelativeTolerance) << c.name << (shade ? " shaded" : " evaluated");
        }
    }
}

// The light in the volume (issue 42): nradEvaluateVolume and nradShadeVolume against nradEvaluateVolumeBatch and
// eval::shadeVolume, on grid and tree assets, blended or not; the surfaces' evaluation beside them unchanged.
TEST(Gpu, VolumeQueryMatchesTheCpuRuntime) {
    NRAD_NEED_VULKAN();
    const GBuffer points = randomPoints(20000, 12);
    for (bool tree : {false, true})
        for (float band : {0.0f, 0.125f}) {
            // On the tree the surfaces decode linearly and the volume exponentially (format::kFlagVolumeExponential,
            // the GPU buffer's word 41); on the grid both as the topology says, exponentially.
            format::Asset a = test::randomAsset({9}, format::WeightEncoding::Float16,
                                                tree ? format::OutputTransform::ClampedLinear : format::OutputTransform::Exponential, 11,
                                                glm::uvec3(4, 3, 5), band);
            if (tree) a.header.flags |= format::kFlagVolumeExponential;
            if (tree) {
                ASSERT_TRUE(makeTreeAsset(a));
            }
            std::mt19937 rng(21);
            std::uniform_real_distribution<float> u(-0.6f, 0.6f);
            for (float& w : a.weights) w = format::halfToFloat(format::floatToHalf(u(rng)));
            // The volume's networks in other cells than the surfaces' (every third), other scales and weights.
            a.volumeVoxels.clear();
            for (uint32_t c = 0; c < (tree ? 90u : 60u); c += 3) a.volumeVoxels.push_back({c, 0.25f + 0.01f * float(c)});
            a.volumeWeights.resize(a.volumeVoxels.size() * a.topology.parameterCount());
            for (float& w : a.volumeWeights) w = format::halfToFloat(format::floatToHalf(u(rng)));
            a.header.flags |= format::kFlagScatteredRadiance | format::kFlagDemodulated;
            nrad::Asset asset = load(a);
            for (bool shade : {false, true}) {
                const Agreement r = compare(runOnGpu(*vk, asset, points, shade, nullptr, true), runVolumeOnCpu(asset, points, shade));
                std::printf("volume, %s%s %-8s worst relative difference %.3g\n", tree ? "tree" : "grid", band > 0 ? ", blended" : "",
                            shade ? "shade" : "evaluate", r.worst);
                EXPECT_EQ(r.flagMismatches, 0u);
                EXPECT_EQ(r.nonFinite, 0u);
                EXPECT_LE(r.worst, kRelativeTolerance) << (tree ? "tree" : "grid") << (shade ? " shaded" : " evaluated");
                const Agreement surfaces = compare(runOnGpu(*vk, asset, points, shade), runOnCpu(asset, points, shade));
                EXPECT_LE(surfaces.worst, kRelativeTolerance) << "the surfaces beside the volume";
                EXPECT_EQ(surfaces.flagMismatches, 0u);
            }
        }
    // An asset without volume networks: every valid point reads 0, NRAD_POINT_EMPTY_VOXEL.
    nrad::Asset plain = load(test::randomAsset({9}, format::WeightEncoding::Float16, format::OutputTransform::Exponential, 4));
    const Result r = runOnGpu(*vk, plain, points, false, nullptr, true);
    size_t empty = 0;
    for (size_t i = 0; i < r.flags.size(); ++i) {
        empty += r.flags[i] == NRAD_POINT_EMPTY_VOXEL;
        if (r.flags[i] == NRAD_POINT_EMPTY_VOXEL) {
            EXPECT_EQ(r.rgb[3 * i], 0.0f);
        }
    }
    EXPECT_GT(empty, points.count() * 9 / 10);
}

// HLSL (issue 42): nrad.hlsl, nrad.glsl's source through glslang's HLSL front end, in nrad_evaluate.hlsl: every entry
// point (evaluate, shade, the volume's two) against the CPU runtime on grid and tree assets, blended or not, other
// topologies and extreme values, within the GLSL's tolerance.
TEST(Gpu, HlslMatchesTheCpuRuntime) {
    NRAD_NEED_VULKAN();
    const GBuffer points = randomPoints(20000, 17);
    struct Case {
        const char* name;
        std::vector<uint32_t> hidden;
        format::OutputTransform transform;
        float band;
        bool tree;
        bool extreme;
    };
    const std::vector<Case> cases = {
        {"grid, exponential", {9}, format::OutputTransform::Exponential, 0.0f, false, false},
        {"grid, linear, 16-8 hidden, blended", {16, 8}, format::OutputTransform::ClampedLinear, 0.0625f, false, false},
        {"tree, blended", {9}, format::OutputTransform::Exponential, 0.125f, true, false},
        {"extreme weights and scales, exp", {9}, format::OutputTransform::Exponential, 0.125f, false, true},
    };
    for (const Case& c : cases) {
        format::Asset a = test::randomAsset(c.hidden, format::WeightEncoding::Float16, c.transform, 11, glm::uvec3(4, 3, 5), c.band);
        if (c.tree) {
            ASSERT_TRUE(makeTreeAsset(a));
        }
        std::mt19937 rng(23);
        std::uniform_real_distribution<float> u(-0.6f, 0.6f);
        if (c.tree)
            for (float& w : a.weights) w = format::halfToFloat(format::floatToHalf(u(rng)));
        if (c.extreme) {
            for (size_t i = 0; i < a.weights.size(); ++i) a.weights[i] = i % 3 == 0 ? -65504.0f : 65504.0f;
            for (format::VoxelEntry& v : a.voxels) v.scale = 3.0e38f;
        }
        for (uint32_t cell = 1; cell < (c.tree ? 90u : 60u); cell += 4) a.volumeVoxels.push_back({cell, 0.3f});
        a.volumeWeights.resize(a.volumeVoxels.size() * a.topology.parameterCount());
        for (float& w : a.volumeWeights) w = format::halfToFloat(format::floatToHalf(u(rng)));
        a.header.flags |= format::kFlagScatteredRadiance | format::kFlagDemodulated;
        // The linear 16-8 asset's volume decodes exponentially (format::kFlagVolumeExponential), its surfaces linearly.
        if (c.transform == format::OutputTransform::ClampedLinear && !c.extreme) a.header.flags |= format::kFlagVolumeExponential;
        nrad::Asset asset = load(a);
        for (bool volume : {false, true})
            for (bool shade : {false, true}) {
                const Result cpu = volume ? runVolumeOnCpu(asset, points, shade) : runOnCpu(asset, points, shade);
                const Agreement r = compare(runOnGpu(*vk, asset, points, shade, nullptr, volume, NRAD_EVALUATE_HLSL_SPV), cpu);
                std::printf("HLSL %-36s %-6s %-8s worst relative difference %.3g\n", c.name, volume ? "volume" : "", shade ? "shade" : "evaluate",
                            r.worst);
                EXPECT_EQ(r.flagMismatches, 0u) << c.name;
                EXPECT_EQ(r.nonFinite, 0u) << c.name;
                EXPECT_LE(r.worst, kRelativeTolerance) << c.name << (volume ? " volume" : "") << (shade ? " shaded" : " evaluated");
            }
    }
}

TEST(Gpu, Fp32AssetsAreRoundedToFp16) {
    NRAD_NEED_VULKAN();
    const GBuffer points = randomPoints(5000, 8);
    format::Asset a = test::randomAsset({9}, format::WeightEncoding::Float32, format::OutputTransform::Exponential, 4);
    format::Asset rounded = a;
    for (float& w : rounded.weights) w = format::halfToFloat(format::floatToHalf(w));
    nrad::Asset asset = load(a), roundedAsset = load(rounded);
    const Result gpu = runOnGpu(*vk, asset, points, false);
    // The GPU evaluates the fp16-rounded weights: it agrees with the CPU on those within the tolerance, and
    // with the fp32 original only within fp16's rounding.
    EXPECT_LE(compare(gpu, runOnCpu(roundedAsset, points, false)).worst, kRelativeTolerance);
    const double toOriginal = compare(gpu, runOnCpu(asset, points, false)).worst;
    std::printf("fp32 asset: worst relative difference to the fp32 CPU evaluation %.3g\n", toOriginal);
    EXPECT_GT(toOriginal, kRelativeTolerance);  // the rounding is visible: the GPU really used fp16
    EXPECT_LE(toOriginal, 0.05);
}

// Every bundled scene, baked quickly (the agreement does not depend on how well the networks learned), its
// camera's view as a G-buffer, evaluated and shaded on both sides.
TEST(Gpu, BundledScenesGBuffersMatchTheCpuRuntime) {
    NRAD_NEED_VULKAN();
    struct Case {
        const char* scene;
        uint64_t budget;  // > 0: a kd-tree asset
    };
    const std::vector<Case> cases = {{"scenes/cornell-box/cornell-box.gltf", 0},
                                     {"scenes/cornell-box/cornell-box.gltf", 16384},
                                     {"scenes/cornell-box-glossy/cornell-box-glossy.gltf", 0},
                                     {"scenes/split-rooms/split-rooms.gltf", 0},
                                     {"scenes/stress/cornell-box-scale-1e4/cornell-box-scale-1e4.gltf", 0},
                                     {"scenes/stress/cornell-box-scale-1e-3/cornell-box-scale-1e-3.gltf", 0},
                                     {"scenes/stress/degenerate/degenerate.gltf", 0},
                                     {"scenes/stress/furnace-0.99/furnace-0.99.gltf", 0},
                                     {"scenes/stress/radiance-span/radiance-span.gltf", 0},
                                     {"scenes/stress/tiny-emitter/tiny-emitter.gltf", 0}};
    for (const Case& c : cases) {
        Scene scene = loadGltf(test::sourcePath(c.scene));
        BakeSettings s;
        s.samples.points = 20000;
        s.samples.paths = 4;
        s.train.epochs = 60;
        s.train.patience = 60;
        s.partition.budgetBytes = c.budget;
        nrad::Asset asset = load(bakeScene(scene, s).asset);
        Accel accel(scene);
        const GBuffer g = renderGBuffer(scene, accel, 160, 120);
        ASSERT_GT(g.count(), 1000u) << c.scene;
        for (bool shade : {false, true}) {
            const Agreement r = compare(runOnGpu(*vk, asset, g, shade), runOnCpu(asset, g, shade));
            std::printf("%-64s %s %-8s worst relative difference %.3g\n", c.scene, c.budget ? "tree" : "grid",
                        shade ? "shade" : "evaluate", r.worst);
            EXPECT_EQ(r.flagMismatches, 0u) << c.scene;
            EXPECT_EQ(r.nonFinite, 0u) << c.scene;
            EXPECT_LE(r.worst, kRelativeTolerance) << c.scene << (shade ? " shaded" : " evaluated");
        }
    }
}

// The example engine integration (examples/vulkan_gbuffer): its rasterised, GPU-shaded image of the Cornell
// box, with a sphere placed after the bake (shaded through the volume query, nradShadeVolume), agrees with the CPU
// runtime on its own G-buffer (the example's exit status) and with `nrad render --asset --insert` of the same view
// (ray-cast first hits, 16 jittered samples per pixel): the same image up to the anti-aliasing of edges.
int shell(const std::string& command, std::string& output) {
    FILE* pipe = popen((command + " 2>&1").c_str(), "r");
    char buf[4096];
    size_t n;
    while ((n = fread(buf, 1, sizeof buf, pipe)) > 0) output.append(buf, n);
    const int status = pclose(pipe);
    return WIFEXITED(status) ? WEXITSTATUS(status) : -1;
}

TEST(Gpu, ExampleEngineImageMatchesTheCpuRender) {
    NRAD_NEED_VULKAN();
    const std::string scenePath = test::sourcePath("scenes/cornell-box/cornell-box.gltf");
    Scene scene = loadGltf(scenePath);
    BakeSettings s;
    s.samples.points = 20000;
    s.samples.paths = 8;
    s.train.epochs = 100;
    s.volume.enabled = true;
    s.volume.pointsPerCell = 300;
    s.volume.paths = 8;
    const std::string sphere = test::sourcePath("scenes/objects/sphere.gltf") + "@0.40,0.10,0.12";
    const std::string dir = test::temporaryDirectory(), assetPath = dir + "/cb.nrad";
    const std::vector<uint8_t> bytes = format::encode(bakeScene(scene, s).asset);
    std::ofstream(assetPath, std::ios::binary).write(reinterpret_cast<const char*>(bytes.data()), std::streamsize(bytes.size()));
    std::string out;
    ASSERT_EQ(shell("'" + std::string(NRAD_VULKAN_EXAMPLE) + "' '" + scenePath + "' '" + assetPath + "' '" + dir +
                        "/gpu.exr' --width 192 --height 192 --repeat 1 --insert '" + sphere + "'",
                    out),
              0)
        << out;
    std::printf("%s", out.c_str());
    const size_t at = out.find(" of inserted objects");
    ASSERT_NE(at, std::string::npos) << out;
    EXPECT_GT(std::atoi(out.c_str() + out.rfind('(', at) + 1), 1000) << "the sphere's pixels";
    ASSERT_EQ(shell("'" + test::nradExecutable() + "' render '" + scenePath + "' --asset '" + assetPath + "' -o '" + dir +
                        "/cpu.exr' --width 192 --height 192 --spp 16 --insert '" + sphere + "'",
                    out),
              0)
        << out;
    const Image gpu = readExr(dir + "/gpu.exr"), cpu = readExr(dir + "/cpu.exr");
    const ImageMetrics m = compareImages(gpu, cpu);
    const ErrorDistribution e = errorDistribution(gpu, cpu);
    std::printf("example vs nrad render --asset: relMSE %.3g, median relative error %.3g, 99th percentile %.3g\n", m.relMse,
                e.medianRelativeError, e.p99RelativeError);
    EXPECT_LE(e.medianRelativeError, 1e-3);  // inside surfaces: the same radiance
    EXPECT_LE(m.relMse, 0.01);  // edges: a pixel centre against 16 jittered samples
}

}  // namespace
}  // namespace nrad
