// Texture lookups (bilinear, wrap modes) and the sRGB transfer functions.
#include "baker/scene/texture.h"

#include <algorithm>
#include <cmath>
#include <cstdint>
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

// The lookup by its definition, every texel index through the wrap mode (what Texture::sample computed before
// its footprint inside the image skipped the wrapping): the reference for the fast path.
int wrapPlain(int i, int n, WrapMode mode) {
    switch (mode) {
        case WrapMode::ClampToEdge: return std::clamp(i, 0, n - 1);
        case WrapMode::MirroredRepeat: {
            const int m = ((i % (2 * n)) + 2 * n) % (2 * n);
            return m < n ? m : 2 * n - 1 - m;
        }
        case WrapMode::Repeat:
        default: return ((i % n) + n) % n;
    }
}

glm::vec4 plainSample(const Texture& t, glm::vec2 uv) {
    float x = uv.x * float(t.width) - 0.5f, y = uv.y * float(t.height) - 0.5f;
    if (!std::isfinite(x) || !std::isfinite(y)) return t.average;
    const float rangeX = float(2 * t.width * 1024), rangeY = float(2 * t.height * 1024);
    if (!(std::abs(x) < rangeX)) x = std::fmod(x, rangeX);
    if (!(std::abs(y) < rangeY)) y = std::fmod(y, rangeY);
    const float fx = std::floor(x), fy = std::floor(y), tx = x - fx, ty = y - fy;
    const int x0 = int(fx), y0 = int(fy);
    const int xa = wrapPlain(x0, t.width, t.wrapS), xb = wrapPlain(x0 + 1, t.width, t.wrapS);
    const int ya = wrapPlain(y0, t.height, t.wrapT), yb = wrapPlain(y0 + 1, t.height, t.wrapT);
    auto texel = [&](int xi, int yi) {
        const size_t i = size_t(yi) * size_t(t.width) + size_t(xi);
        if (t.bytes.empty()) return t.texels[i];
        const uint8_t* b = &t.bytes[4 * i];
        return glm::vec4(t.colour[b[0]], t.colour[b[1]], t.colour[b[2]], t.alpha[b[3]]);
    };
    const glm::vec4 a = texel(xa, ya), b = texel(xb, ya), c = texel(xa, yb), d = texel(xb, yb);
    return (a * (1.0f - tx) + b * tx) * (1.0f - ty) + (c * (1.0f - tx) + d * tx) * ty;
}

// sample() takes the four texels as row-major neighbours where the footprint lies inside the image and reads
// a byte texel's four bytes as one word: every lookup must give the definition's bits, inside, on the edges
// (the footprint half outside, wrapped) and outside, for every wrap mode, byte and float texels, images down to
// one texel wide; and the prefetch hint, anywhere, changes nothing.
TEST(Texture, FastFootprintIsTheWrappedDefinitionBitForBit) {
    std::mt19937 rng(11);
    const WrapMode modes[] = {WrapMode::Repeat, WrapMode::ClampToEdge, WrapMode::MirroredRepeat};
    for (int size : {1, 2, 5, 64})
        for (bool asBytes : {true, false})
            for (WrapMode ws : modes)
                for (WrapMode wt : modes) {
                    Texture t;
                    t.width = size;
                    t.height = size + 1;
                    t.wrapS = ws;
                    t.wrapT = wt;
                    const size_t n = size_t(t.width) * size_t(t.height);
                    if (asBytes) {
                        t.colour = linearOfSrgbByte();
                        t.alpha = unitOfByte();
                        for (size_t i = 0; i < 4 * n; ++i) t.bytes.push_back(uint8_t(rng() & 255u));
                    } else {
                        std::uniform_real_distribution<float> v(0.0f, 4.0f);
                        for (size_t i = 0; i < n; ++i) t.texels.emplace_back(v(rng), v(rng), v(rng), v(rng));
                    }
                    t.computeAverage();
                    std::uniform_real_distribution<float> inside(0.0f, 1.0f), near(-1.5f, 2.5f);
                    const float edges[] = {0.0f, 0.5f / float(size), 1.0f - 0.5f / float(size), 1.0f, -1e-7f, 1.0f + 1e-7f};
                    for (int i = 0; i < 3000; ++i) {
                        glm::vec2 uv;
                        if (i % 3 == 0)
                            uv = {inside(rng), inside(rng)};
                        else if (i % 3 == 1)
                            uv = {near(rng), near(rng)};
                        else
                            uv = {edges[rng() % 6], i % 2 ? edges[rng() % 6] : inside(rng)};
                        t.prefetch(uv);
                        const glm::vec4 got = t.sample(uv), want = plainSample(t, uv);
                        ASSERT_EQ(std::memcmp(&got, &want, sizeof got), 0)
                            << "size " << size << (asBytes ? " bytes" : " floats") << " uv " << uv.x << ", " << uv.y;
                    }
                    for (glm::vec2 uv : {glm::vec2(NAN, 0.5f), glm::vec2(0.5f, INFINITY), glm::vec2(3e9f, -3e9f)}) {
                        t.prefetch(uv);
                        const glm::vec4 got = t.sample(uv), want = plainSample(t, uv);
                        EXPECT_EQ(std::memcmp(&got, &want, sizeof got), 0) << "uv " << uv.x << ", " << uv.y;
                    }
                }
}

// Texture storage: large images aligned to 2 MiB (where the kernel may back them with huge pages), small ones
// plain; either holds and copies its values.
TEST(Texture, LargeImagesAreAlignedForHugePages) {
    std::vector<uint8_t, LargePageAllocator<uint8_t>> large(size_t(4) << 20, 7), small(100, 3);
    EXPECT_EQ(reinterpret_cast<uintptr_t>(large.data()) % (uintptr_t(2) << 20), 0u);
    EXPECT_EQ(large[(size_t(4) << 20) - 1], 7);
    EXPECT_EQ(small[99], 3);
    auto copy = large;
    EXPECT_EQ(copy.size(), large.size());
    EXPECT_EQ(std::memcmp(copy.data(), large.data(), large.size()), 0);
}

}  // namespace
}  // namespace nrad
