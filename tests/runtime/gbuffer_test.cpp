// nradShadeGBuffer (issue 18): strided fp32/fp16 attributes, directions from an eye position, normalisation on
// input, RGB/RGBA fp32/fp16 output, against nradEvaluateBatch / nradShadeBatch on the same values in fp32
// (bit for bit before the output's own rounding); invalid vectors flagged; bad descriptions refused.
#include <nrad/format.h>
#include <nrad/nrad.h>
#include <nrad/nrad.hpp>

#include <cmath>
#include <cstring>
#include <limits>
#include <random>

#include <gtest/gtest.h>

#include "support/random_asset.h"

namespace nrad {
namespace {

// What an engine's G-buffer texel might be: position fp32, normal fp16 (padded), base colour etc. elsewhere.
struct Texel {
    float position[3];
    uint16_t normal[4];
    uint16_t direction[3];
    uint16_t pad;
};

// The runtime's normalisation, for the expected values: v x (1 / sqrt(|v|^2)).
void normalise(float v[3]) {
    const float len2 = v[0] * v[0] + v[1] * v[1] + v[2] * v[2];
    const float inv = 1.0f / std::sqrt(len2);
    for (int k = 0; k < 3; ++k) v[k] *= inv;
}

struct Fixture {
    nrad::Asset asset;
    format::Asset source;
    std::vector<Texel> texels;
    std::vector<NradSurface> surfaces;
    // The texels' values in fp32, normalised as the runtime does: the reference batches' inputs.
    std::vector<float> p, n, d;
    const float eye[3] = {0.3f, -0.2f, 9.0f};

    explicit Fixture(size_t count) {
        source = test::randomAsset({9}, format::WeightEncoding::Float16, format::OutputTransform::Exponential, 4,
                                   glm::uvec3(4, 3, 3), 0.125f);
        source.header.flags |= format::kFlagScatteredRadiance | format::kFlagDemodulated;
        const std::vector<uint8_t> bytes = format::encode(source);
        EXPECT_EQ(asset.loadFromMemory(bytes.data(), bytes.size()), NRAD_OK);
        std::mt19937 rng(6);
        std::uniform_real_distribution<float> u(-1.0f, 1.0f), u01(0.0f, 1.0f);
        for (size_t i = 0; i < count; ++i) {
            Texel t{};
            float nn[3], dd[3];
            for (int k = 0; k < 3; ++k) {
                t.position[k] = source.grid.lower[k] + (source.grid.upper[k] - source.grid.lower[k]) * (0.5f + 0.55f * u(rng));
                nn[k] = 3.0f * u(rng);  // not unit length
                dd[k] = u(rng);
            }
            for (int k = 0; k < 3; ++k) {
                t.normal[k] = format::floatToHalf(nn[k]);
                t.direction[k] = format::floatToHalf(dd[k]);
            }
            texels.push_back(t);
            surfaces.push_back({{u01(rng), u01(rng), u01(rng)}, u01(rng) < 0.3f ? 1.0f : 0.0f, u01(rng), 1.0f, {u01(rng), 0.0f, 0.0f}});
        }
    }

    NradGBuffer describe(bool eyeMode) const {
        NradGBuffer g;
        std::memset(&g, 0, sizeof g);
        g.structSize = sizeof(NradGBuffer);
        g.flags = eyeMode ? NRAD_GBUFFER_EYE : 0;
        g.count = texels.size();
        g.position = {texels.data()->position, sizeof(Texel), NRAD_FORMAT_F32};
        g.normal = {texels.data()->normal, sizeof(Texel), NRAD_FORMAT_F16};
        g.direction = {texels.data()->direction, sizeof(Texel), NRAD_FORMAT_F16};
        for (int k = 0; k < 3; ++k) g.eye[k] = eye[k];
        return g;
    }

    // The reference inputs for one mode.
    void referenceInputs(bool eyeMode) {
        p.clear();
        n.clear();
        d.clear();
        for (const Texel& t : texels) {
            float nn[3], dd[3];
            for (int k = 0; k < 3; ++k) {
                nn[k] = format::halfToFloat(t.normal[k]);
                dd[k] = eyeMode ? eye[k] - t.position[k] : format::halfToFloat(t.direction[k]);
                p.push_back(t.position[k]);
            }
            normalise(nn);
            normalise(dd);
            n.insert(n.end(), nn, nn + 3);
            d.insert(d.end(), dd, dd + 3);
        }
    }
};

TEST(GBuffer, StridedFp16InputsMatchTheBatchCallsBitForBit) {
    Fixture f(5000);  // several tiles
    const size_t count = f.texels.size();
    for (bool eyeMode : {false, true})
        for (bool shade : {false, true}) {
            f.referenceInputs(eyeMode);
            std::vector<float> expected(3 * count);
            std::vector<uint8_t> expectedFlags(count), flags(count);
            if (shade)
                ASSERT_EQ(f.asset.shadeBatch(count, f.p.data(), f.n.data(), f.d.data(), f.surfaces.data(), expected.data(),
                                             expectedFlags.data()),
                          NRAD_OK);
            else
                ASSERT_EQ(f.asset.evaluateBatch(count, f.p.data(), f.n.data(), f.d.data(), expected.data(), expectedFlags.data()),
                          NRAD_OK);
            NradGBuffer g = f.describe(eyeMode);
            g.surfaces = shade ? f.surfaces.data() : nullptr;
            g.pointFlags = flags.data();
            // RGBA fp32, padded to 5 floats per point.
            std::vector<float> rgba(5 * count, -1.0f);
            g.output = rgba.data();
            g.outputStride = 5 * sizeof(float);
            g.outputFormat = NRAD_FORMAT_F32;
            g.outputChannels = 4;
            std::vector<uint8_t> scratch(nradGetScratchSize());
            ASSERT_EQ(nradShadeGBuffer(f.asset.get(), &g, scratch.data(), scratch.size()), NRAD_OK);
            EXPECT_EQ(flags, expectedFlags);
            for (size_t i = 0; i < count; ++i) {
                for (int c = 0; c < 3; ++c)
                    ASSERT_EQ(std::memcmp(&rgba[5 * i + size_t(c)], &expected[3 * i + size_t(c)], 4), 0)
                        << "point " << i << " eye " << eyeMode << " shade " << shade;
                ASSERT_EQ(rgba[5 * i + 3], 1.0f);
                ASSERT_EQ(rgba[5 * i + 4], -1.0f) << "wrote past its stride";
            }
            // RGB fp16, tightly packed, the thread's own scratch.
            std::vector<uint16_t> half(3 * count);
            g.output = half.data();
            g.outputStride = 0;
            g.outputFormat = NRAD_FORMAT_F16;
            g.outputChannels = 3;
            ASSERT_EQ(nradShadeGBuffer(f.asset.get(), &g, nullptr, 0), NRAD_OK);
            for (size_t i = 0; i < 3 * count; ++i) ASSERT_EQ(half[i], format::floatToHalf(expected[i])) << i;
        }
}

TEST(GBuffer, ZeroOrNonFiniteVectorsAreInvalidInputs) {
    Fixture f(64);
    f.texels[3].normal[0] = f.texels[3].normal[1] = f.texels[3].normal[2] = 0;  // zero normal
    f.texels[7].direction[1] = 0x7C00;  // +inf
    NradGBuffer g = f.describe(false);
    g.surfaces = f.surfaces.data();
    std::vector<float> rgb(3 * f.texels.size());
    std::vector<uint8_t> flags(f.texels.size());
    g.output = rgb.data();
    g.outputChannels = 3;
    g.pointFlags = flags.data();
    ASSERT_EQ(nradShadeGBuffer(f.asset.get(), &g, nullptr, 0), NRAD_OK);
    for (size_t i : {size_t(3), size_t(7)}) {
        EXPECT_EQ(flags[i], NRAD_POINT_INVALID_INPUT) << i;
        for (int c = 0; c < 3; ++c) EXPECT_EQ(rgb[3 * i + size_t(c)], f.surfaces[i].emission[c]) << "emission only";
    }
    EXPECT_EQ(flags[4], NRAD_POINT_OK);
}

TEST(GBuffer, BadDescriptionsAreRefused) {
    Fixture f(16);
    std::vector<float> rgb(4 * 16);
    NradGBuffer good = f.describe(false);
    good.output = rgb.data();
    good.outputChannels = 3;
    ASSERT_EQ(nradShadeGBuffer(f.asset.get(), &good, nullptr, 0), NRAD_OK);
    std::vector<uint8_t> scratch(nradGetScratchSize());
    auto refused = [&](void (*change)(NradGBuffer&), size_t scratchBytes = 0) {
        NradGBuffer g = good;
        change(g);
        return nradShadeGBuffer(f.asset.get(), &g, scratchBytes ? scratch.data() : nullptr, scratchBytes) == NRAD_ERROR_INVALID_ARGUMENT;
    };
    EXPECT_TRUE(refused([](NradGBuffer& g) { g.structSize = 8; }));
    EXPECT_TRUE(refused([](NradGBuffer& g) { g.outputChannels = 2; }));
    EXPECT_TRUE(refused([](NradGBuffer& g) { g.outputFormat = 7; }));
    EXPECT_TRUE(refused([](NradGBuffer& g) { g.normal.format = 2; }));
    EXPECT_TRUE(refused([](NradGBuffer& g) { g.position.data = nullptr; }));
    EXPECT_TRUE(refused([](NradGBuffer& g) { g.direction.data = nullptr; }));
    EXPECT_TRUE(refused([](NradGBuffer& g) { g.output = nullptr; }));
    EXPECT_TRUE(refused([](NradGBuffer& g) { g.flags = 64; }));
    EXPECT_TRUE(refused([](NradGBuffer&) {}, nradGetScratchSize() - 1));  // scratch too small
    EXPECT_FALSE(refused([](NradGBuffer& g) {  // no directions needed with an eye
        g.direction.data = nullptr;
        g.flags = NRAD_GBUFFER_EYE;
    }));
    EXPECT_EQ(nradShadeGBuffer(nullptr, &good, nullptr, 0), NRAD_ERROR_INVALID_ARGUMENT);
    EXPECT_EQ(nradShadeGBuffer(f.asset.get(), nullptr, nullptr, 0), NRAD_ERROR_INVALID_ARGUMENT);
}

}  // namespace
}  // namespace nrad
