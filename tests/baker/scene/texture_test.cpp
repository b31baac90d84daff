// Texture lookups (bilinear, wrap modes) and the sRGB transfer functions.
#include "baker/scene/texture.h"

#include <cstring>
#include <random>

#include <gtest/gtest.h>

namespace nrad {
namespace {

Texture twoByOne() {
    Texture t;
    t.width = 2;
    t.height = 1;
    t.texels = {glm::vec4(0.0f), glm::vec4(1.0f)};
    return t;
}

TEST(Texture, BilinearBetweenTexelCentres) {
    Texture t = twoByOne();
    t.wrapS = WrapMode::ClampToEdge;
    EXPECT_FLOAT_EQ(t.sample({0.25f, 0.5f}).x, 0.0f);  // centre of texel 0
    EXPECT_FLOAT_EQ(t.sample({0.75f, 0.5f}).x, 1.0f);  // centre of texel 1
    EXPECT_FLOAT_EQ(t.sample({0.5f, 0.5f}).x, 0.5f);
    EXPECT_FLOAT_EQ(t.sample({-3.0f, 0.5f}).x, 0.0f);  // clamped
}

TEST(Texture, RepeatAndMirror) {
    Texture t = twoByOne();
    t.wrapS = WrapMode::Repeat;
    EXPECT_FLOAT_EQ(t.sample({1.25f, 0.5f}).x, 0.0f);
    EXPECT_FLOAT_EQ(t.sample({0.0f, 0.5f}).x, 0.5f);  // halfway between texel 1 (wrapped) and texel 0
    t.wrapS = WrapMode::MirroredRepeat;
    EXPECT_FLOAT_EQ(t.sample({1.25f, 0.5f}).x, 1.0f);  // mirrored: texel 1 again
}

// Coordinates far outside [0, 1) (reduced by fmod before the texel index wraps) and just outside it (wrapped
// without reduction) give the texels their wrap mode says, for either sign.
TEST(Texture, FarAndNearCoordinatesWrapAlike) {
    Texture t = twoByOne();
    t.wrapS = WrapMode::Repeat;
    for (float u : {0.25f, 0.75f, 0.5f, 0.1f})
        for (float k : {-5000.0f, -3.0f, -1.0f, 1.0f, 4.0f, 3000.0f}) {
            SCOPED_TRACE(testing::Message() << "repeat u " << u << " + " << k);
            EXPECT_NEAR(t.sample({u + k, 0.5f}).x, t.sample({u, 0.5f}).x, 2e-3f);
        }
    EXPECT_FLOAT_EQ(t.sample({1.0e6f + 0.25f, 0.5f}).x, 0.0f);  // exact in float: texel 0's centre
    EXPECT_FLOAT_EQ(t.sample({-1.0e6f + 0.75f, 0.5f}).x, 1.0f);
    t.wrapS = WrapMode::MirroredRepeat;
    for (float u : {0.25f, 0.75f, 0.1f})
        for (float k : {-6000.0f, -2.0f, 2.0f, 4000.0f}) {  // even periods: mirrored twice, the texture itself
            SCOPED_TRACE(testing::Message() << "mirror u " << u << " + " << k);
            EXPECT_NEAR(t.sample({u + k, 0.5f}).x, t.sample({u, 0.5f}).x, 2e-3f);
        }
    EXPECT_FLOAT_EQ(t.sample({-0.75f, 0.5f}).x, 1.0f);  // mirrored once: texel 1 at -0.75
    t.wrapS = WrapMode::ClampToEdge;
    EXPECT_FLOAT_EQ(t.sample({5000.0f, 0.5f}).x, 1.0f);
    EXPECT_FLOAT_EQ(t.sample({-5000.0f, 0.5f}).x, 0.0f);
}

TEST(Texture, SrgbRoundTripAndKnownValues) {
    EXPECT_NEAR(srgbToLinear(0.5f), 0.214041f, 1e-5f);
    EXPECT_NEAR(srgbToLinear(1.0f), 1.0f, 1e-6f);
    EXPECT_NEAR(linearToSrgb(0.214041f), 0.5f, 1e-5f);
    for (float c = 0.0f; c <= 1.0f; c += 0.01f) EXPECT_NEAR(linearToSrgb(srgbToLinear(c)), c, 1e-5f);
}

// 8-bit textures keep their bytes and decode them in lookups: every lookup must give the bits of the same
// texture decoded to floats on load, for both transfer tables, every wrap mode and coordinates in and far
// outside [0, 1); the average likewise.
TEST(Texture, ByteTexelsLookUpAsTheirDecodedFloats) {
    std::mt19937 rng(4);
    for (const float* table : {unitOfByte(), linearOfSrgbByte()})
        for (WrapMode wrap : {WrapMode::Repeat, WrapMode::ClampToEdge, WrapMode::MirroredRepeat}) {
            Texture bytes, floats;
            bytes.width = floats.width = 7;
            bytes.height = floats.height = 5;
            bytes.wrapS = floats.wrapS = wrap;
            bytes.wrapT = floats.wrapT = WrapMode::Repeat;
            bytes.colour = table;
            bytes.alpha = unitOfByte();
            for (int i = 0; i < 7 * 5 * 4; ++i) bytes.bytes.push_back(uint8_t(rng() & 255u));
            for (int i = 0; i < 7 * 5; ++i) {
                const uint8_t* b = &bytes.bytes[size_t(4 * i)];
                floats.texels.emplace_back(table[b[0]], table[b[1]], table[b[2]], unitOfByte()[b[3]]);
            }
            ASSERT_EQ(bytes.texelCount(), floats.texelCount());
            std::uniform_real_distribution<float> u(-3.0f, 3.0f);
            for (int i = 0; i < 2000; ++i) {
                const glm::vec2 uv(u(rng), i % 2 ? u(rng) : u(rng) * 1e4f);
                const glm::vec4 a = bytes.sample(uv), b = floats.sample(uv);
                ASSERT_EQ(std::memcmp(&a, &b, sizeof a), 0) << "uv " << uv.x << ", " << uv.y;
            }
            bytes.computeAverage();
            floats.computeAverage();
            EXPECT_EQ(std::memcmp(&bytes.average, &floats.average, sizeof bytes.average), 0);
        }
    // The tables are the conversions they name.
    for (int v = 0; v < 256; ++v) {
        EXPECT_EQ(unitOfByte()[v], float(v) / 255.0f);
        EXPECT_EQ(linearOfSrgbByte()[v], srgbToLinear(float(v) / 255.0f));
    }
}

}  // namespace
}  // namespace nrad
