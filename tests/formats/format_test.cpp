// The .nrad byte layout: golden bytes of a tiny asset, round trips, every truncated prefix, bad magic,
// other versions, trailing bytes, flipped bytes caught by the CRCs, fp16 conversions, the voxel rule.
#include <nrad/eval.h>
#include <nrad/format.h>

#include <cmath>
#include <fstream>
#include <limits>

#include <gtest/gtest.h>

#include "support/test_paths.h"

namespace nrad::format {
namespace {

Asset tinyAsset(WeightEncoding encoding = WeightEncoding::Float16) {
    Asset a;
    a.grid.lower[0] = a.grid.lower[1] = a.grid.lower[2] = 0.0f;
    a.grid.upper[0] = 1.0f;
    a.grid.upper[1] = 2.0f;
    a.grid.upper[2] = 4.0f;
    a.grid.dims[0] = 1;
    a.grid.dims[1] = 1;
    a.grid.dims[2] = 2;
    a.topology.hiddenWidths = {2};
    a.topology.weightEncoding = encoding;
    a.topology.outputTransform = OutputTransform::Exponential;
    a.voxels = {{1, 2.0f}};
    size_t n = a.topology.parameterCount();  // 9*2 + 2 + 3*2 + 3 = 29
    for (size_t i = 0; i < n; ++i) a.weights.push_back(float(int(i) - 14) * 0.25f);
    a.metadata = "{\"k\":1}";
    a.header.flags = kFlagScatteredRadiance;
    return a;
}

std::vector<uint8_t> readGolden(const char* name = "tiny.nrad") {
    std::ifstream f(test::sourcePath(std::string("tests/data/golden/") + name), std::ios::binary);
    return std::vector<uint8_t>((std::istreambuf_iterator<char>(f)), std::istreambuf_iterator<char>());
}

TEST(Format, ParameterCountOfThePaperNetwork) {
    Topology t;
    EXPECT_EQ(t.parameterCount(), 120u);  // 9*9 + 9 + 3*9 + 3
}

TEST(Format, GoldenBytes) {
    std::vector<uint8_t> bytes = encode(tinyAsset());
    std::vector<uint8_t> golden = readGolden();
    ASSERT_FALSE(golden.empty()) << "tests/data/golden/tiny.nrad missing";
    EXPECT_EQ(bytes, golden);
    // Spot checks of the layout by hand: magic, version 2.0, the scattered-radiance flag, header size, 5
    // sections, file size, table at 64.
    const uint8_t magic[8] = {'N', 'R', 'A', 'D', 0x0D, 0x0A, 0x1A, 0x0A};
    EXPECT_EQ(std::memcmp(bytes.data(), magic, 8), 0);
    EXPECT_EQ(bytes[8], 2);
    EXPECT_EQ(bytes[9], 0);
    EXPECT_EQ(bytes[10], 0);
    EXPECT_EQ(bytes[12], 1);
    EXPECT_EQ(bytes[16], 64);
    EXPECT_EQ(bytes[20], 5);
    EXPECT_EQ(uint64_t(bytes[24]) | (uint64_t(bytes[25]) << 8), bytes.size());
    EXPECT_EQ(bytes[32], 64);
    // First section record: GRID at offset 64 + 5 * 32 = 224, 40 bytes.
    EXPECT_EQ(std::string(bytes.begin() + 64, bytes.begin() + 68), "GRID");
    EXPECT_EQ(bytes[72], 224);
    EXPECT_EQ(bytes[80], 40);
    // Size: header 64 + table 160 + GRID 40 + TOPO 28 (+4 pad) + VOXL 12 (+4 pad) + WGHT 58 (+6 pad) + META 7.
    EXPECT_EQ(bytes.size(), 64u + 160u + 40u + 32u + 16u + 64u + 7u);
}

TEST(Format, RoundTripFp16AndFp32) {
    for (WeightEncoding enc : {WeightEncoding::Float16, WeightEncoding::Float32}) {
        Asset a = tinyAsset(enc);
        std::vector<uint8_t> bytes = encode(a);
        Asset b;
        ASSERT_EQ(decode(bytes.data(), bytes.size(), b), DecodeStatus::Ok);
        EXPECT_EQ(b.grid.dims[2], 2u);
        EXPECT_EQ(b.grid.upper[2], 4.0f);
        EXPECT_EQ(b.topology.hiddenWidths, std::vector<uint32_t>{2});
        EXPECT_EQ(b.topology.outputTransform, OutputTransform::Exponential);
        EXPECT_EQ(b.topology.weightEncoding, enc);
        ASSERT_EQ(b.voxels.size(), 1u);
        EXPECT_EQ(b.voxels[0].index, 1u);
        EXPECT_EQ(b.voxels[0].scale, 2.0f);
        EXPECT_EQ(b.weights, a.weights);  // multiples of 1/4 are exact in fp16
        EXPECT_EQ(b.metadata, "{\"k\":1}");
        EXPECT_EQ(b.header.flags, kFlagScatteredRadiance);
    }
}

TEST(Format, VersionOneAssetsAreRefusedAndUnknownFlagsRejected) {
    // Version 1 networks stored L with the surface's emission in it; version 2 readers refuse them rather
    // than add the emission twice (docs/format.md, "Versions").
    std::vector<uint8_t> v1 = readGolden("tiny-v1.nrad");
    ASSERT_FALSE(v1.empty());
    Asset out;
    EXPECT_EQ(decode(v1.data(), v1.size(), out), DecodeStatus::UnsupportedVersion);
    std::vector<uint8_t> b = encode(tinyAsset());
    b[12] |= 0x80;  // a flag this reader does not know, with a valid header CRC
    uint32_t crc = crc32(b.data(), 60);
    for (int i = 0; i < 4; ++i) b[size_t(60 + i)] = uint8_t(crc >> (8 * i));
    EXPECT_EQ(decode(b.data(), b.size(), out), DecodeStatus::BadHeader);
    Asset plain = tinyAsset();
    plain.header.flags = 0;  // networks storing L: still a valid asset
    b = encode(plain);
    ASSERT_EQ(decode(b.data(), b.size(), out), DecodeStatus::Ok);
    EXPECT_EQ(out.header.flags, 0u);
}

TEST(Format, EveryTruncatedPrefixIsRejected) {
    std::vector<uint8_t> bytes = encode(tinyAsset());
    for (size_t n = 0; n < bytes.size(); ++n) {
        Asset out;
        DecodeStatus s = decode(bytes.data(), n, out);
        EXPECT_NE(s, DecodeStatus::Ok) << "prefix " << n;
        if (n >= 64) {
            EXPECT_EQ(s, DecodeStatus::Truncated) << "prefix " << n;
        }
    }
}

TEST(Format, BadMagicVersionAndTrailingBytes) {
    std::vector<uint8_t> bytes = encode(tinyAsset());
    Asset out;
    std::vector<uint8_t> b = bytes;
    b[0] = 'X';
    EXPECT_EQ(decode(b.data(), b.size(), out), DecodeStatus::BadMagic);
    b = bytes;
    b[4] = 0x0A;  // CR LF turned into LF by a text-mode transfer
    EXPECT_EQ(decode(b.data(), b.size(), out), DecodeStatus::BadMagic);
    b = bytes;
    b[8] = 3;  // a future major version
    EXPECT_EQ(decode(b.data(), b.size(), out), DecodeStatus::UnsupportedVersion);
    b = bytes;
    b[10] = 7;  // a newer minor version is accepted when its CRC is right
    uint32_t crc = crc32(b.data(), 60);
    for (int i = 0; i < 4; ++i) b[size_t(60 + i)] = uint8_t(crc >> (8 * i));
    EXPECT_EQ(decode(b.data(), b.size(), out), DecodeStatus::Ok);
    b = bytes;
    b.push_back(0);
    EXPECT_EQ(decode(b.data(), b.size(), out), DecodeStatus::TrailingBytes);
}

TEST(Format, EveryFlippedByteIsCaught) {
    std::vector<uint8_t> bytes = encode(tinyAsset());
    for (size_t i = 0; i < bytes.size(); ++i) {
        std::vector<uint8_t> b = bytes;
        b[i] ^= 0x10;
        Asset out;
        EXPECT_NE(decode(b.data(), b.size(), out), DecodeStatus::Ok) << "byte " << i;
    }
}

TEST(Format, Crc32KnownValue) {
    const char* s = "123456789";
    EXPECT_EQ(crc32(reinterpret_cast<const uint8_t*>(s), 9), 0xCBF43926u);  // the standard check value
}

TEST(Format, HalfConversions) {
    EXPECT_EQ(floatToHalf(1.0f), 0x3C00);
    EXPECT_EQ(floatToHalf(-2.0f), 0xC000);
    EXPECT_EQ(floatToHalf(65504.0f), 0x7BFF);
    EXPECT_EQ(floatToHalf(1e9f), 0x7BFF);  // saturates, never Inf
    EXPECT_EQ(floatToHalf(5.9604645e-8f), 0x0001);  // smallest subnormal
    EXPECT_EQ(floatToHalf(1.0f + 1.0f / 2048.0f), 0x3C00);  // halfway: round to even
    EXPECT_EQ(floatToHalf(1.0f + 3.0f / 2048.0f), 0x3C02);
    EXPECT_EQ(halfToFloat(0x3555), 0.333251953125f);
    for (uint32_t h = 0; h < 0x7C00; ++h) ASSERT_EQ(floatToHalf(halfToFloat(uint16_t(h))), h) << h;
}

TEST(Format, VoxelRuleOnBorders) {
    Grid g;
    g.lower[0] = g.lower[1] = g.lower[2] = 0.0f;
    g.upper[0] = g.upper[1] = g.upper[2] = 3.0f;
    g.dims[0] = g.dims[1] = g.dims[2] = 3;
    auto voxelX = [&](float x) {
        float p[3] = {x, 0.5f, 0.5f};
        eval::Location at = eval::locate(g, p);
        return at.voxel < 0 ? -1 : at.coord[0];
    };
    EXPECT_EQ(voxelX(0.0f), 0);
    EXPECT_EQ(voxelX(1.0f), 1);  // an interior border belongs to the voxel above
    EXPECT_EQ(voxelX(3.0f), 2);  // the upper face belongs to the last voxel
    EXPECT_EQ(voxelX(-1e-6f), -1);
    EXPECT_EQ(voxelX(std::numeric_limits<float>::quiet_NaN()), -1);
    float p[3] = {2.5f, 0.5f, 1.5f};
    eval::Location at = eval::locate(g, p);
    EXPECT_EQ(at.voxel, 2 + 3 * (0 + 3 * 1));
    EXPECT_FLOAT_EQ(at.local[0], 0.0f);
    EXPECT_FLOAT_EQ(at.local[1], 0.0f);
    EXPECT_FLOAT_EQ(at.local[2], 0.0f);
    float upper[3] = {3.0f, 3.0f, 3.0f};
    at = eval::locate(g, upper);  // the upper corner: the last voxel's +1 face
    EXPECT_EQ(at.local[0], 1.0f);
}

TEST(Format, DecoderRejectsInvalidContent) {
    Asset out;
    auto reencode = [](Asset a) { return encodeUnchecked(a); };  // invalid on purpose: encode() would stop
    Asset a = tinyAsset();
    a.voxels[0].index = 2;  // outside a grid of 2 voxels
    std::vector<uint8_t> b = reencode(a);
    EXPECT_EQ(decode(b.data(), b.size(), out), DecodeStatus::BadVoxels);
    a = tinyAsset(WeightEncoding::Float32);
    a.weights[3] = std::numeric_limits<float>::infinity();
    b = reencode(a);
    EXPECT_EQ(decode(b.data(), b.size(), out), DecodeStatus::BadWeights);
    a = tinyAsset();
    a.weights.pop_back();
    b = reencode(a);
    EXPECT_EQ(decode(b.data(), b.size(), out), DecodeStatus::BadWeights);
    a = tinyAsset();
    a.grid.upper[1] = a.grid.lower[1];
    b = reencode(a);
    EXPECT_EQ(decode(b.data(), b.size(), out), DecodeStatus::BadGrid);
    a = tinyAsset();
    a.topology.hiddenWidths = {0};
    b = reencode(a);
    EXPECT_EQ(decode(b.data(), b.size(), out), DecodeStatus::BadTopology);
}


// A writer that breaks encode()'s preconditions is a bug: it stops before writing, naming the condition.
TEST(FormatDeathTest, EncodeStopsAtBrokenPreconditions) {
    Asset a = tinyAsset();
    ASSERT_FALSE(encode(a).empty());
    a.voxels[0].index = 2;  // outside a grid of 2 voxels
    EXPECT_DEATH(encode(a), "internal check failed: a.voxels\\[i\\].index < cells");
    a = tinyAsset(WeightEncoding::Float32);
    a.weights[3] = std::numeric_limits<float>::quiet_NaN();
    EXPECT_DEATH(encode(a), "internal check failed: std::isfinite\\(w\\)");
    a = tinyAsset();
    a.weights.pop_back();
    EXPECT_DEATH(encode(a), "internal check failed: a.weights.size\\(\\) == ");
    a = tinyAsset();
    a.voxels[0].scale = 0.0f;
    EXPECT_DEATH(encode(a), "a.voxels\\[i\\].scale > 0.0f");
    a = tinyAsset();
    a.header.flags |= kFlagTree;  // and no tree
    EXPECT_DEATH(encode(a), "validateTree");
}

// Format 2.1: kFlagBlended and the band in GRID's last four bytes; written as 2.1 only when blended, so
// 2.0 readers still load everything else (and reject the flag rather than draw seams).
TEST(Format, BlendBandRoundTripsAndIsValidated) {
    Asset a = tinyAsset();
    std::vector<uint8_t> b = encode(a);
    EXPECT_EQ(b[10], 0);  // minor version 0 without blending
    Asset out;
    ASSERT_EQ(decode(b.data(), b.size(), out), DecodeStatus::Ok);
    EXPECT_EQ(out.grid.blendBand, 0.0f);
    a.header.flags |= kFlagBlended;
    a.grid.blendBand = 0.125f;
    b = encode(a);
    EXPECT_EQ(b[10], 1);
    ASSERT_EQ(decode(b.data(), b.size(), out), DecodeStatus::Ok);
    EXPECT_EQ(out.grid.blendBand, 0.125f);
    EXPECT_EQ(out.header.flags, kFlagScatteredRadiance | kFlagBlended);
    for (float bad : {0.0f, -0.1f, 0.5001f, 1.0f, std::numeric_limits<float>::quiet_NaN(), std::numeric_limits<float>::infinity()}) {
        a.grid.blendBand = bad;
        b = encode(a);
        EXPECT_EQ(decode(b.data(), b.size(), out), DecodeStatus::BadGrid) << bad;
    }
    a.grid.blendBand = 0.5f;  // the largest: the bands of a voxel's two faces meet in its middle
    b = encode(a);
    EXPECT_EQ(decode(b.data(), b.size(), out), DecodeStatus::Ok);
    // Without the flag the four bytes must stay 0 (a writer's band without its flag is an error, not ignored).
    Asset plain = tinyAsset();
    b = encode(plain);
    const size_t grid = size_t(b[64 + 8]) | size_t(b[64 + 9]) << 8;  // the first section record (GRID): its offset
    b[grid + 36] = 0x3E;
    const uint8_t* rec = b.data() + 64;
    const uint32_t crc = crc32(b.data() + grid, 40);
    for (int i = 0; i < 4; ++i) b[size_t(64 + 24 + i)] = uint8_t(crc >> (8 * i));
    const uint32_t tableCrc = crc32(rec, size_t(b[20]) * kSectionRecordSize);
    for (int i = 0; i < 4; ++i) b[size_t(40 + i)] = uint8_t(tableCrc >> (8 * i));
    const uint32_t headerCrc = crc32(b.data(), 60);
    for (int i = 0; i < 4; ++i) b[size_t(60 + i)] = uint8_t(headerCrc >> (8 * i));
    EXPECT_EQ(decode(b.data(), b.size(), out), DecodeStatus::BadGrid);
}

// nrad/eval.h supports(): one network inside a voxel, 2 / 4 / 8 within the band of a face / edge / corner,
// none across the grid's boundary, weights summing to 1 in increasing voxel order, positions relative to
// each voxel, and a partition of unity that is continuous (and smooth) across the face.
TEST(Format, BlendedSupportsArePartitionsOfUnity) {
    Grid g;
    for (int k = 0; k < 3; ++k) {
        g.lower[k] = -1.0f;
        g.upper[k] = 2.0f;
        g.dims[k] = 3;
    }
    const float factor[3] = {eval::gridFactor(g, 0), eval::gridFactor(g, 1), eval::gridFactor(g, 2)};
    const float band = 0.25f;
    eval::Support s[eval::kMaxSupports];
    auto count = [&](float x, float y, float z) {
        const float p[3] = {x, y, z};
        return eval::supports(g, factor, band, p, s);
    };
    EXPECT_EQ(count(0.5f, 0.5f, 0.5f), 1);
    EXPECT_EQ(s[0].voxel, 13);
    EXPECT_EQ(s[0].weight, 1.0f);
    EXPECT_EQ(count(0.05f, 0.5f, 0.5f), 2);  // x near the face between voxels 0 and 1 of the middle row
    EXPECT_EQ(s[0].voxel, 12);
    EXPECT_EQ(s[1].voxel, 13);
    EXPECT_NEAR(s[0].local[0], 1.1f, 1e-5f);  // beyond the lower voxel's +1 face
    EXPECT_NEAR(s[1].local[0], -0.9f, 1e-5f);
    EXPECT_EQ(count(0.05f, 0.95f, 0.5f), 4);
    EXPECT_EQ(count(0.05f, 0.95f, 1.1f), 8);
    for (int i = 1; i < 8; ++i) EXPECT_LT(s[i - 1].voxel, s[i].voxel);
    float sum = 0.0f;
    for (int i = 0; i < 8; ++i) sum += s[i].weight;
    EXPECT_NEAR(sum, 1.0f, 1e-6f);
    EXPECT_EQ(count(-0.95f, -0.95f, 1.95f), 1);  // bands only at interior faces
    EXPECT_EQ(count(-1.5f, 0.0f, 0.0f), 0);
    EXPECT_EQ(count(0.5f, std::numeric_limits<float>::quiet_NaN(), 0.5f), 0);
    // Band 0: exactly locate().
    const float q[3] = {0.05f, 0.95f, 1.1f};
    ASSERT_EQ(eval::supports(g, factor, 0.0f, q, s), 1);
    const eval::Location at = eval::locate(g, q);
    EXPECT_EQ(s[0].voxel, at.voxel);
    for (int k = 0; k < 3; ++k) EXPECT_EQ(s[0].local[k], at.local[k]);
    // Weight of the upper voxel along x across the face at x = 0: 0 to 1 over the band, 1/2 on the face,
    // continuous with bounded slope (smoothstep: at most 1.5 / (2 band) per voxel), flat at both ends.
    auto upper = [&](float x) {
        const int n = count(x, 0.5f, 0.5f);
        for (int i = 0; i < n; ++i)
            if (s[i].voxel == 13) return s[i].weight;
        return 0.0f;
    };
    EXPECT_EQ(upper(0.0f), 0.5f);
    EXPECT_EQ(upper(-0.3f), 0.0f);
    EXPECT_EQ(upper(0.3f), 1.0f);
    float previous = upper(-0.26f);
    for (int i = 1; i <= 520; ++i) {
        const float x = -0.26f + 0.001f * float(i);
        const float w = upper(x);
        EXPECT_GE(w, previous - 1e-7f) << x;
        EXPECT_LE(std::abs(w - previous), 0.001f * 1.5f / (2.0f * band) * 1.01f + 1e-6f) << x;
        previous = w;
    }
    EXPECT_LT(upper(-0.25f + 0.002f), 1e-4f);
    EXPECT_GT(upper(0.25f - 0.002f), 1.0f - 1e-4f);
    // keepOccupied: an empty neighbour's weight goes to the rest.
    ASSERT_EQ(count(0.05f, 0.95f, 0.5f), 4);
    const int kept = eval::keepOccupied(s, 4, [](int64_t v) { return v != 12; });
    ASSERT_EQ(kept, 3);
    EXPECT_NEAR(s[0].weight + s[1].weight + s[2].weight, 1.0f, 1e-6f);
    EXPECT_EQ(eval::keepOccupied(s, 3, [](int64_t) { return false; }), 0);
}

}  // namespace
}  // namespace nrad::format
