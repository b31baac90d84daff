// Texture lookups (bilinear, wrap modes) and the sRGB transfer functions.
#include "baker/scene/texture.h"

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

}  // namespace
}  // namespace nrad
