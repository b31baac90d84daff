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

TEST(Texture, SrgbRoundTripAndKnownValues) {
    EXPECT_NEAR(srgbToLinear(0.5f), 0.214041f, 1e-5f);
    EXPECT_NEAR(srgbToLinear(1.0f), 1.0f, 1e-6f);
    EXPECT_NEAR(linearToSrgb(0.214041f), 0.5f, 1e-5f);
    for (float c = 0.0f; c <= 1.0f; c += 0.01f) EXPECT_NEAR(linearToSrgb(srgbToLinear(c)), c, 1e-5f);
}

}  // namespace
}  // namespace nrad
