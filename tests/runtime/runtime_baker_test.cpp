// libnrad against the baker: the runtime's evaluation of a baked asset agrees with the baker's own forward pass
// of every network that shades a point (the part of the runtime's tests that needs the baker; the rest build
// and run with the runtime alone, tests/runtime_standalone).
#include <nrad/eval.h>
#include <nrad/format.h>
#include <nrad/nrad.h>
#include <nrad/nrad.hpp>

#include <algorithm>
#include <cmath>
#include <cstdio>

#include <gtest/gtest.h>

#include "baker/bake/baker.h"
#include "baker/nn/mlp.h"
#include "baker/scene/gltf_loader.h"
#include "support/test_paths.h"
#include "support/volume_query.h"

namespace nrad {
namespace {

std::vector<NradKernel> kernels() {
    std::vector<NradKernel> k = {NRAD_KERNEL_SCALAR};
    for (NradKernel c : {NRAD_KERNEL_AVX2, NRAD_KERNEL_AVX512, NRAD_KERNEL_NEON})
        if (nradKernelSupported(c)) k.push_back(c);
    return k;
}

TEST(Runtime, AgreesWithTheBakersForwardPassOnABakedCornellBox) {
    Scene scene = loadGltf(test::sourcePath("scenes/cornell-box-glossy/cornell-box-glossy.gltf"));
    for (format::WeightEncoding enc : {format::WeightEncoding::Float32, format::WeightEncoding::Float16}) {
        BakeSettings s;
        s.samples.points = 2000;
        s.samples.paths = 8;
        s.train.epochs = 100;
        s.encoding = enc;
        BakeResult r = bakeScene(scene, s);
        std::vector<uint8_t> bytes = format::encode(r.asset);
        nrad::Asset asset;
        ASSERT_EQ(asset.loadFromMemory(bytes.data(), bytes.size()), NRAD_OK);
        VoxelGrid grid(scene.bounds, s.grid);
        SurfacePieces pieces(scene.mesh, grid);
        SplitMix64 rng(5);
        double worst = 0.0;
        for (NradKernel k : kernels()) {
            nradSelectKernel(k);
            for (size_t v = 0; v < r.voxels.size(); ++v) {
                const std::vector<uint32_t>& own = pieces.piecesOf(r.voxels[v].voxel);
                ASSERT_FALSE(own.empty());
                for (int i = 0; i < 20; ++i) {
                    float b1, b2;
                    glm::vec3 p = pieces.samplePiece(pieces.pieces()[own[size_t(i) % own.size()]], {rng.uniform(), rng.uniform()}, b1, b2);
                    glm::vec3 n = scene.mesh.geometricNormal(pieces.pieces()[own[size_t(i) % own.size()]].triangle);
                    glm::vec3 d = glm::normalize(n + glm::vec3(0.3f, 0.2f, -0.1f));
                    // The baker's own forward pass of every network that shades p, blended as nrad/eval.h says.
                    const float q[3] = {p.x, p.y, p.z};
                    const float factor[3] = {eval::gridFactor(r.asset.grid, 0), eval::gridFactor(r.asset.grid, 1),
                                             eval::gridFactor(r.asset.grid, 2)};
                    eval::Support sup[eval::kMaxSupports];
                    auto resultOf = [&](int64_t voxel) {
                        return std::find_if(r.voxels.begin(), r.voxels.end(), [&](const VoxelTrainResult& x) { return int64_t(x.voxel) == voxel; });
                    };
                    int count = eval::supports(r.asset.grid, factor, r.asset.grid.blendBand, q, sup);
                    count = eval::keepOccupied(sup, count, [&](int64_t voxel) { return resultOf(voxel) != r.voxels.end(); });
                    ASSERT_GT(count, 0);
                    glm::vec3 expected(0.0f);
                    float scale = 0.0f;
                    for (int j = 0; j < count; ++j) {
                        const VoxelTrainResult& vr = *resultOf(sup[j].voxel);
                        Mlp mlp(s.train.shape);
                        mlp.parameters() = vr.params;
                        MlpWorkspace ws;
                        float in[9], y[3];
                        eval::encodeInputs(sup[j].local, &n.x, &d.x, in);
                        mlp.forward(in, y, ws);
                        expected += sup[j].weight * decodeOutput(r.asset.topology.outputTransform, vr.scale, y);
                        scale = std::max(scale, vr.scale);
                    }
                    float rgb[3];
                    uint32_t flag;
                    ASSERT_EQ(asset.evaluate(&p.x, &n.x, &d.x, rgb, &flag), NRAD_OK);
                    ASSERT_EQ(flag, uint32_t(NRAD_POINT_OK));
                    for (int c = 0; c < 3; ++c) {
                        // Relative to the larger of the value and the voxels' mean radiance (their scale).
                        double rel = std::abs(rgb[c] - expected[c]) / std::max(double(std::abs(expected[c])), double(scale));
                        worst = std::max(worst, rel);
                    }
                }
            }
        }
        // Stated tolerance, relative to max(value, voxel mean radiance): fp32 weights 1e-4 (measured 4e-7),
        // fp16 weights 5e-3 (measured 1.2e-3: 11-bit mantissas).
        std::printf("encoding %d: worst relative difference %.3g\n", int(enc), worst);
        EXPECT_LT(worst, enc == format::WeightEncoding::Float32 ? 1e-4 : 5e-3) << "encoding " << int(enc);
    }
    nradSelectKernel(NRAD_KERNEL_AUTO);
}

// nradEvaluateVolumeBatch against the baker's reading of the same asset's volume networks (the decoded weights,
// nrad/eval.h's blending), on every kernel, for a grid's cells and a kd-tree's leaves (--budget); and an asset
// without them refused.
void expectVolumeQueryAgreesWithTheBaker(const Scene& scene, BakeSettings s) {
    const std::vector<uint8_t> bytes = format::encode(bakeScene(scene, s).asset);
    format::Asset decoded;
    ASSERT_EQ(format::decode(bytes.data(), bytes.size(), decoded), format::DecodeStatus::Ok);
    ASSERT_FALSE(decoded.volumeVoxels.empty());
    if (s.partition.budgetBytes > 0) {
        ASSERT_FALSE(decoded.tree.empty());
        EXPECT_LE(bytes.size(), s.partition.budgetBytes);
        std::printf("--budget %llu: %u leaves, %zu volume networks, %zu bytes\n", (unsigned long long)s.partition.budgetBytes,
                    decoded.leafCount, decoded.volumeVoxels.size(), bytes.size());
    }
    const test::VolumeQuery query(decoded);
    const float scale = query.largestScale();
    nrad::Asset asset;
    ASSERT_EQ(asset.loadFromMemory(bytes.data(), bytes.size()), NRAD_OK);
    NradAssetInfo info;
    ASSERT_EQ(nradGetAssetInfo(asset.get(), &info), NRAD_OK);
    EXPECT_EQ(info.volumeNetworks, decoded.volumeVoxels.size());
    SplitMix64 rng(7);
    const size_t n = 500;
    std::vector<float> positions(3 * n), normals(3 * n), rgb(3 * n);
    for (size_t i = 0; i < n; ++i) {
        glm::vec3 nn(rng.uniform() - 0.5f, rng.uniform() - 0.5f, rng.uniform() - 0.5f);
        nn = glm::normalize(nn + glm::vec3(0.0f, 1e-3f, 0.0f));
        for (int k = 0; k < 3; ++k) {
            positions[3 * i + size_t(k)] = decoded.grid.lower[k] + rng.uniform() * (decoded.grid.upper[k] - decoded.grid.lower[k]);
            normals[3 * i + size_t(k)] = nn[k];
        }
    }
    double worst = 0.0;
    for (NradKernel k : kernels()) {
        nradSelectKernel(k);
        std::vector<uint8_t> flags(n, 255);
        ASSERT_EQ(nradEvaluateVolumeBatch(asset.get(), n, positions.data(), normals.data(), rgb.data(), flags.data()), NRAD_OK);
        for (size_t i = 0; i < n; ++i) {
            // A kd-tree leaf without free space (inside a box) has no volume network: zero, as the baker reads it.
            ASSERT_TRUE(flags[i] == uint8_t(NRAD_POINT_OK) || (decoded.volumeVoxels.size() < decoded.leafCount && flags[i] == uint8_t(NRAD_POINT_EMPTY_VOXEL)));
            const glm::vec3 p(positions[3 * i], positions[3 * i + 1], positions[3 * i + 2]);
            const glm::vec3 nn(normals[3 * i], normals[3 * i + 1], normals[3 * i + 2]);
            const glm::vec3 expected = query(p, nn);
            for (int c = 0; c < 3; ++c)
                worst = std::max(worst, double(std::abs(rgb[3 * i + size_t(c)] - expected[c])) / std::max(std::abs(expected[c]), scale));
        }
    }
    nradSelectKernel(NRAD_KERNEL_AUTO);
    std::printf("volume query: worst relative difference %.3g\n", worst);
    EXPECT_LT(worst, 1e-4);  // the same fp16-decoded weights on both sides: only the order of the sums differs
    // The glossy response, where baked: at the same points and normals, seen from directions in their hemispheres.
    EXPECT_EQ(info.glossyNetworks, decoded.glossyVoxels.size());
    ASSERT_EQ(decoded.glossyVoxels.empty(), !s.volume.glossy) << "the glossy response baked when asked for, only then";
    if (!decoded.glossyVoxels.empty()) {
        const test::VolumeQuery glossy(decoded, true);
        std::vector<float> views(3 * n);
        for (size_t i = 0; i < n; ++i) {
            glm::vec3 v = glm::normalize(glm::vec3(rng.uniform() - 0.5f, rng.uniform() - 0.5f, rng.uniform() - 0.5f) + glm::vec3(1e-3f, 0.0f, 0.0f));
            if (glm::dot(v, glm::vec3(normals[3 * i], normals[3 * i + 1], normals[3 * i + 2])) < 0.0f) v = -v;
            for (int k = 0; k < 3; ++k) views[3 * i + size_t(k)] = v[k];
        }
        double worstGlossy = 0.0;
        for (NradKernel k : kernels()) {
            nradSelectKernel(k);
            ASSERT_EQ(nradEvaluateVolumeGlossyBatch(asset.get(), n, positions.data(), normals.data(), views.data(), rgb.data(), nullptr), NRAD_OK);
            for (size_t i = 0; i < n; ++i) {
                const glm::vec3 expected = glossy(glm::vec3(positions[3 * i], positions[3 * i + 1], positions[3 * i + 2]),
                                                  glm::vec3(normals[3 * i], normals[3 * i + 1], normals[3 * i + 2]),
                                                  glm::vec3(views[3 * i], views[3 * i + 1], views[3 * i + 2]));
                for (int c = 0; c < 3; ++c)
                    worstGlossy = std::max(worstGlossy, double(std::abs(rgb[3 * i + size_t(c)] - expected[c])) /
                                                            std::max(std::abs(expected[c]), glossy.largestScale()));
            }
        }
        nradSelectKernel(NRAD_KERNEL_AUTO);
        std::printf("glossy query: worst relative difference %.3g\n", worstGlossy);
        EXPECT_LT(worstGlossy, 1e-4);
    } else {
        EXPECT_EQ(nradEvaluateVolumeGlossyBatch(asset.get(), n, positions.data(), normals.data(), normals.data(), rgb.data(), nullptr),
                  NRAD_ERROR_INVALID_ARGUMENT);
    }
    // An asset without volume networks has no volume query.
    s.volume.enabled = false;
    const std::vector<uint8_t> plain = format::encode(bakeScene(scene, s).asset);
    nrad::Asset without;
    ASSERT_EQ(without.loadFromMemory(plain.data(), plain.size()), NRAD_OK);
    EXPECT_EQ(nradEvaluateVolumeBatch(without.get(), n, positions.data(), normals.data(), rgb.data(), nullptr), NRAD_ERROR_INVALID_ARGUMENT);
}

TEST(Runtime, VolumeQueryAgreesWithTheBaker) {
    const Scene scene = loadGltf(test::sourcePath("scenes/cornell-box/cornell-box.gltf"));
    BakeSettings s;
    s.samples.points = 2000;
    s.samples.paths = 4;
    s.train.epochs = 60;
    s.volume.enabled = true;
    s.volume.pointsPerCell = 200;
    s.volume.paths = 4;
    expectVolumeQueryAgreesWithTheBaker(scene, s);
    s.partition.budgetBytes = 8 * 1024;  // the cells a kd-tree's leaves, with the glossy response
    s.partition.minLeafSamples = 64;
    s.volume.glossy = true;
    expectVolumeQueryAgreesWithTheBaker(scene, s);
}

}  // namespace
}  // namespace nrad
