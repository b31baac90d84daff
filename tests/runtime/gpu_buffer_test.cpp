// nradPackGpuBuffer's layout (docs/runtime.md, "GPU buffers"): golden bytes of the golden asset's buffer,
// every field checked by hand against the decoded asset, a kd-tree asset's nodes, widths and boxes, and the
// errors. Needs no GPU (label unit); tests/gpu runs the buffers.
#include <nrad/eval.h>
#include <nrad/format.h>
#include <nrad/nrad.h>
#include <nrad/nrad.hpp>

#include <cstdlib>
#include <cstring>
#include <fstream>

#include <gtest/gtest.h>

#include "support/random_asset.h"
#include "support/test_paths.h"
#include "support/test_trees.h"

namespace nrad {
namespace {

std::vector<uint8_t> readFile(const std::string& path) {
    std::ifstream f(path, std::ios::binary);
    return std::vector<uint8_t>((std::istreambuf_iterator<char>(f)), std::istreambuf_iterator<char>());
}

std::vector<uint32_t> pack(const nrad::Asset& asset) {
    size_t bytes = 0;
    EXPECT_EQ(nradGetGpuBufferSize(asset.get(), &bytes), NRAD_OK);
    EXPECT_EQ(bytes % 4, 0u);
    std::vector<uint32_t> words(bytes / 4, 0xDEADBEEFu);
    EXPECT_EQ(nradPackGpuBuffer(asset.get(), words.data(), bytes), NRAD_OK);
    return words;
}

float floatOf(uint32_t w) {
    float f;
    std::memcpy(&f, &w, 4);
    return f;
}

uint16_t halfAt(const std::vector<uint32_t>& w, uint32_t first, size_t i) { return uint16_t(w[first + i / 2] >> (16 * (i & 1))); }

TEST(GpuBuffer, GoldenBytesOfTheGoldenAsset) {
    const std::vector<uint8_t> file = readFile(test::sourcePath("tests/data/golden/tiny.nrad"));
    nrad::Asset asset;
    ASSERT_EQ(asset.loadFromMemory(file.data(), file.size()), NRAD_OK);
    const std::vector<uint32_t> w = pack(asset);
    const std::string goldenPath = test::sourcePath("tests/data/golden/tiny-gpu.bin");
    if (const char* update = std::getenv("NRAD_UPDATE_GOLDEN"); update && std::string(update) == "1") {
        std::ofstream(goldenPath, std::ios::binary).write(reinterpret_cast<const char*>(w.data()), std::streamsize(w.size() * 4));
    }
    const std::vector<uint8_t> golden = readFile(goldenPath);
    ASSERT_EQ(golden.size(), w.size() * 4) << "tests/data/golden/tiny-gpu.bin";
    EXPECT_EQ(std::memcmp(golden.data(), w.data(), golden.size()), 0);

    // The same buffer, field by field, against the decoded asset (1x1x2 grid, voxel 1 holds a 9-2-3 network).
    format::Asset a;
    ASSERT_EQ(format::decode(file.data(), file.size(), a), format::DecodeStatus::Ok);
    ASSERT_EQ(w.size(), 64u + 2 + 1 + 15);  // header, cell table, scales, 29 halves
    EXPECT_EQ(w[0], 0x5047524Eu);  // "NRGP"
    EXPECT_EQ(w[1], uint32_t(NRAD_GPU_LAYOUT_VERSION));
    EXPECT_EQ(w[2], a.header.flags);
    EXPECT_EQ(w[3], 1u);  // exponential
    for (int k = 0; k < 3; ++k) {
        EXPECT_EQ(floatOf(w[4 + k]), a.grid.lower[k]);
        EXPECT_EQ(floatOf(w[7 + k]), a.grid.upper[k]);
        EXPECT_EQ(w[10 + k], a.grid.dims[k]);
        EXPECT_EQ(floatOf(w[13 + k]), eval::gridFactor(a.grid, k));
    }
    EXPECT_EQ(floatOf(w[16]), 0.0f);  // not blended
    EXPECT_EQ(w[17], 1u);
    EXPECT_EQ(w[18], 2u);
    for (int i = 19; i < 26; ++i) EXPECT_EQ(w[size_t(i)], 0u);
    EXPECT_EQ(w[26], 29u);
    EXPECT_EQ(w[27], 1u);  // networks
    EXPECT_EQ(w[28], 2u);  // cells
    EXPECT_EQ(w[29], 0u);  // no tree
    EXPECT_EQ(w[30], 64u);  // cell table
    EXPECT_EQ(w[31], 66u);  // scales
    EXPECT_EQ(w[32], 67u);
    EXPECT_EQ(w[33], 67u);
    EXPECT_EQ(w[34], 67u);
    EXPECT_EQ(w[35], 67u);  // weights
    EXPECT_EQ(w[36], 82u);  // total words
    for (int i = 37; i < 64; ++i) EXPECT_EQ(w[size_t(i)], 0u);
    EXPECT_EQ(w[64], 0xFFFFFFFFu);  // voxel 0: no network
    EXPECT_EQ(w[65], 0u);
    EXPECT_EQ(floatOf(w[66]), a.voxels[0].scale);
    for (size_t i = 0; i < 29; ++i) EXPECT_EQ(halfAt(w, 67, i), format::floatToHalf(a.weights[i])) << i;
    EXPECT_EQ(w[81] >> 16, 0u);  // the odd half's padding
}

TEST(GpuBuffer, TreeNodesWidthsAndBoxes) {
    format::Asset a = test::randomAsset({9}, format::WeightEncoding::Float16, format::OutputTransform::Exponential, 3,
                                        glm::uvec3(16, 16, 16), 0.125f);
    a.header.flags |= format::kFlagTree;
    a.tree = test::randomTree(a.grid.dims, 40, 2);
    uint32_t leaves = 0;
    std::vector<format::TreeBox> boxes;
    ASSERT_TRUE(format::validateTree(a.grid.dims, a.tree, leaves, &boxes));
    a.voxels.clear();
    for (uint32_t l = 1; l < leaves; l += 3) a.voxels.push_back({l, 1.0f + float(l)});
    a.weights.assign(a.voxels.size() * a.topology.parameterCount(), 0.25f);
    const std::vector<uint8_t> bytes = format::encode(a);
    nrad::Asset asset;
    ASSERT_EQ(asset.loadFromMemory(bytes.data(), bytes.size()), NRAD_OK);
    const std::vector<uint32_t> w = pack(asset);
    const uint32_t nodes = w[32], widths = w[33], boxAt = w[34], table = w[30];
    ASSERT_EQ(w[28], leaves);
    ASSERT_EQ(w[29], uint32_t(a.tree.size()));
    EXPECT_EQ(table, 64u);
    EXPECT_EQ(nodes, table + leaves + uint32_t(a.voxels.size()));
    EXPECT_EQ(widths, nodes + 2 * uint32_t(a.tree.size()));
    EXPECT_EQ(boxAt, widths + uint32_t(a.tree.size()));
    EXPECT_EQ(w[35], boxAt + 6 * leaves);
    EXPECT_EQ(w[36], w[35] + (uint32_t(a.weights.size()) + 1) / 2);
    EXPECT_EQ(size_t(w[36]), w.size());
    const std::vector<float> expectedWidths = eval::treeBandWidths(a.grid.dims, a.tree, 0.125f);
    for (size_t i = 0; i < a.tree.size(); ++i) {
        EXPECT_EQ(w[nodes + 2 * i], a.tree[i].axis | (a.tree[i].split << 2));
        EXPECT_EQ(w[nodes + 2 * i + 1], a.tree[i].child);
        EXPECT_EQ(floatOf(w[widths + i]), expectedWidths[i]);
    }
    for (uint32_t l = 0; l < leaves; ++l) {
        for (int k = 0; k < 3; ++k) {
            EXPECT_EQ(w[boxAt + 6 * l + uint32_t(k)], boxes[l].lo[k]);
            EXPECT_EQ(w[boxAt + 6 * l + 3 + uint32_t(k)], boxes[l].hi[k]);
        }
        const auto it = std::find_if(a.voxels.begin(), a.voxels.end(), [&](const format::VoxelEntry& e) { return e.index == l; });
        EXPECT_EQ(w[table + l], it == a.voxels.end() ? 0xFFFFFFFFu : uint32_t(it - a.voxels.begin()));
    }
    EXPECT_EQ(halfAt(w, w[35], 0), format::floatToHalf(0.25f));
}

TEST(GpuBuffer, Errors) {
    format::Asset a = test::randomAsset({9}, format::WeightEncoding::Float16, format::OutputTransform::Exponential, 1);
    std::vector<uint8_t> bytes = format::encode(a);
    nrad::Asset asset;
    ASSERT_EQ(asset.loadFromMemory(bytes.data(), bytes.size()), NRAD_OK);
    size_t size = 0;
    EXPECT_EQ(nradGetGpuBufferSize(nullptr, &size), NRAD_ERROR_INVALID_ARGUMENT);
    EXPECT_EQ(nradGetGpuBufferSize(asset.get(), nullptr), NRAD_ERROR_INVALID_ARGUMENT);
    ASSERT_EQ(nradGetGpuBufferSize(asset.get(), &size), NRAD_OK);
    std::vector<uint32_t> buffer(size / 4 + 1, 7u);
    EXPECT_EQ(nradPackGpuBuffer(asset.get(), nullptr, size), NRAD_ERROR_INVALID_ARGUMENT);
    EXPECT_EQ(nradPackGpuBuffer(asset.get(), buffer.data(), size - 4), NRAD_ERROR_INVALID_ARGUMENT);
    EXPECT_EQ(buffer[0], 7u);  // nothing written
    EXPECT_EQ(nradPackGpuBuffer(asset.get(), reinterpret_cast<uint8_t*>(buffer.data()) + 2, size + 2), NRAD_ERROR_INVALID_ARGUMENT);
    EXPECT_EQ(buffer[0], 7u);
    EXPECT_EQ(nradPackGpuBuffer(asset.get(), buffer.data(), size + 4), NRAD_OK);
    EXPECT_EQ(buffer.back(), 7u);  // nothing beyond the size

    // A hidden layer wider than the GLSL's arrays.
    format::Asset wide = test::randomAsset({NRAD_GPU_MAX_HIDDEN_WIDTH + 1}, format::WeightEncoding::Float16,
                                           format::OutputTransform::Exponential, 1);
    bytes = format::encode(wide);
    nrad::Asset wideAsset;
    ASSERT_EQ(wideAsset.loadFromMemory(bytes.data(), bytes.size()), NRAD_OK);
    EXPECT_EQ(nradGetGpuBufferSize(wideAsset.get(), &size), NRAD_ERROR_UNSUPPORTED_GPU_LAYOUT);
    EXPECT_EQ(size, 0u);
    EXPECT_EQ(nradPackGpuBuffer(wideAsset.get(), buffer.data(), buffer.size() * 4), NRAD_ERROR_UNSUPPORTED_GPU_LAYOUT);
    EXPECT_STRNE(nradStatusString(NRAD_ERROR_UNSUPPORTED_GPU_LAYOUT), "unknown status");
}

}  // namespace
}  // namespace nrad
