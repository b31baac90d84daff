// nradShadeGBuffer (issue 18): strided fp32/fp16 attributes, directions from an eye position, normalisation on
// input, RGB/RGBA fp32/fp16 output, against nradEvaluateBatch / nradShadeBatch on the same values in fp32
// (bit for bit before the output's own rounding); invalid vectors flagged; bad descriptions refused.
#include <nrad/eval.h>
#include <nrad/format.h>
#include <nrad/nrad.h>
#include <nrad/nrad.hpp>

#include <cmath>
#include <cstring>
#include <limits>
#include <random>

#include <gtest/gtest.h>

#include "runtime/src/testing.h"  // rt::testing::gbufferBlocksSoFar(): which path the vector kernels took
#include "support/random_asset.h"
#include "support/shade_reference.h"
#include "support/test_trees.h"

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
            ASSERT_EQ(f.asset.evaluateBatch(count, f.p.data(), f.n.data(), f.d.data(), expected.data(), expectedFlags.data()),
                      NRAD_OK);
            if (shade) test::shadeReference(f.source.header.flags, count, f.n.data(), f.d.data(), f.surfaces.data(), expected.data());
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

// One attribute of a layout test: its own tightly sized buffer (the last point's bytes end the allocation, so
// a read past them is caught by the sanitizers), `stride` bytes per point, fp16 or fp32.
struct Attribute {
    std::vector<uint8_t> bytes;
    size_t stride;
    bool half;
    Attribute(const std::vector<float>& xyz, size_t stride_, bool half_) : stride(stride_), half(half_) {
        const size_t count = xyz.size() / 3, size = half ? 6 : 12;
        bytes.assign((count - 1) * stride + size, 0xA5);
        for (size_t i = 0; i < count; ++i)
            for (int k = 0; k < 3; ++k) {
                const float v = xyz[3 * i + size_t(k)];
                if (half) {
                    const uint16_t h = format::floatToHalf(v);
                    std::memcpy(&bytes[i * stride + 2 * size_t(k)], &h, 2);
                } else {
                    std::memcpy(&bytes[i * stride + 4 * size_t(k)], &v, 4);
                }
            }
    }
    // The values the runtime reads.
    float value(size_t i, int k) const {
        if (half) {
            uint16_t h;
            std::memcpy(&h, &bytes[i * stride + 2 * size_t(k)], 2);
            return format::halfToFloat(h);
        }
        float v;
        std::memcpy(&v, &bytes[i * stride + 4 * size_t(k)], 4);
        return v;
    }
    NradAttribute describe() const {
        return {bytes.data(), stride, half ? NRAD_FORMAT_F16 : NRAD_FORMAT_F32};
    }
};

// Every kernel this CPU runs, the scalar one first.
std::vector<NradKernel> kernels() {
    std::vector<NradKernel> k = {NRAD_KERNEL_SCALAR};
    for (NradKernel c : {NRAD_KERNEL_AVX2, NRAD_KERNEL_AVX512, NRAD_KERNEL_NEON})
        if (nradKernelSupported(c)) k.push_back(c);
    return k;
}

// Coherent points (runs of 11 in one cell of the grid, bands included, as a rasterised surface gives them),
// with a few zero normals and points outside the grid: every path of the vector G-buffer reader is taken
// (whole vectors in one voxel, blended, spanning voxels, empty voxels, invalid points, the partial last
// vector), and every layout of attributes and pixels must give the batch calls' bits, in every kernel (each
// vector kernel has its own transposing readers and writer: a lane out of place fails here).
TEST(GBuffer, EveryLayoutThroughTheVectorPathMatchesTheBatchCalls) {
    for (const NradKernel kernel : kernels()) {
        SCOPED_TRACE("kernel " + std::to_string(int(kernel)));
        ASSERT_EQ(nradSelectKernel(kernel), NRAD_OK);
        const uint64_t before = rt::testing::gbufferBlocksSoFar(), treeBefore = rt::testing::treeBlocksSoFar();
        // A blended grid asset, and a kd-tree asset over an 8^3 lattice of the same box (cells of the lattice are
        // the runs' cells below; leaves hold several).
        format::Asset grid =
            test::randomAsset({9}, format::WeightEncoding::Float16, format::OutputTransform::Exponential, 9,
                              glm::uvec3(4, 3, 3), 0.125f);
        grid.header.flags |= format::kFlagScatteredRadiance | format::kFlagDemodulated;  // the whole shading contract
        format::Asset tree = grid;
        ASSERT_FALSE(test::makeRandomTreeAsset(tree, 8, 12, 3, 7, 5).empty());
        for (const format::Asset* sourceAsset : {&grid, &tree}) {
            const format::Asset& source = *sourceAsset;
            nrad::Asset asset;
            const std::vector<uint8_t> assetBytes = format::encode(source);
            ASSERT_EQ(asset.loadFromMemory(assetBytes.data(), assetBytes.size()), NRAD_OK);
            // Three tiles, the last one partial: a count that is not a whole number of vectors (the last point is
            // read by the scalar gather), and one that is (the vector reader's exact reads of the last point).
            for (const size_t count : {size_t(2101), size_t(2112)}) {
                std::mt19937 rng(12);
                std::uniform_real_distribution<float> u(0.0f, 1.0f), s(-1.0f, 1.0f);
                std::vector<float> p(3 * count), n(3 * count), d(3 * count);
                std::vector<NradSurface> surfaces(count);
                uint32_t cell[3] = {0, 0, 0};
                for (size_t i = 0; i < count; ++i) {
                    if (i % 11 == 0)
                        for (int k = 0; k < 3; ++k) cell[k] = uint32_t(rng() % source.grid.dims[k]);
                    for (int k = 0; k < 3; ++k) {
                        const float size =
                            (source.grid.upper[k] - source.grid.lower[k]) / float(source.grid.dims[k]);
                        p[3 * i + size_t(k)] = source.grid.lower[k] + size * (float(cell[k]) + u(rng));
                        n[3 * i + size_t(k)] = 2.0f * s(rng);  // not unit length
                        d[3 * i + size_t(k)] = s(rng);
                    }
                    if (i % 97 == 5) n[3 * i] = n[3 * i + 1] = n[3 * i + 2] = 0.0f;  // invalid
                    if (i % 89 == 7) p[3 * i + 1] = source.grid.upper[1] + 0.5f;     // outside
                    surfaces[i] = {{u(rng), u(rng), u(rng)},
                                   u(rng) < 0.3f ? 1.0f : u(rng) < 0.5f ? 0.0f : u(rng),
                                   u(rng),
                                   u(rng) < 0.5f ? 1.0f : 1.5f * u(rng),
                                   {u(rng), 0.0f, 4.0f * u(rng)}};
                    // Material terms out of range or not finite now and then: the shading contract's clamps and NaN
                    // rules in every lane position.
                    const float odd[] = {-0.5f, 1.5f, std::numeric_limits<float>::quiet_NaN(),
                                         std::numeric_limits<float>::infinity(), -0.0f};
                    if (i % 13 == 3) surfaces[i].roughness = odd[(i / 13) % 5];
                    if (i % 17 == 4) surfaces[i].metallic = odd[(i / 17) % 5];
                    if (i % 19 == 6) surfaces[i].baseColor[(i / 19) % 3] = odd[(i / 19) % 5];
                    if (i % 23 == 8) surfaces[i].emission[(i / 23) % 3] = odd[(i / 23) % 5];
                    if (i % 29 == 9) surfaces[i].specular = odd[(i / 29) % 5];
                }
                const float eye[3] = {0.25f, 7.0f, -3.0f};
                constexpr size_t kPaddedSurface = sizeof(NradSurface) + 7;
                std::vector<uint8_t> paddedSurfaces(count * kPaddedSurface, 0xC3);
                for (size_t i = 0; i < count; ++i)
                    std::memcpy(&paddedSurfaces[i * kPaddedSurface], &surfaces[i], sizeof(NradSurface));
                struct Input {
                    size_t positionStride, normalStride, directionStride;
                    bool positionHalf, normalHalf, directionHalf;
                };
                const Input inputs[] = {
                    {28, 28, 28, false, true, true},  // one texel: position fp32, normal and direction fp16
                    {12, 6, 6, false, true, true},    // tightly packed
                    {6, 12, 16, true, false, false},  // fp16 positions, fp32 vectors
                    {13, 7, 9, false, true, true},    // odd strides
                    {4, 2, 6, false, true, true},     // overlapping attributes (strides under their size)
                    {8, 8, 8, true, true, true},      // fp16 in 8-byte records (AVX-512 reads them in whole vectors)
                };
                struct Output {
                    bool half;
                    int channels;
                    size_t stride;
                };
                const Output outputs[] = {{true, 4, 0},   {true, 4, 12},  {true, 3, 0}, {false, 3, 0},
                                          {false, 4, 0}, {false, 4, 20}, {true, 3, 10}};
                for (const Input& in : inputs)
                    for (int mode = 0; mode < 4; ++mode) {  // unit vectors or not, eye or per-pixel directions
                        const bool unit = mode & 1, eyeMode = mode & 2;
                        const Attribute position(p, in.positionStride, in.positionHalf),
                            normal(n, in.normalStride, in.normalHalf),
                            direction(d, in.directionStride, in.directionHalf);
                        // The reference batches' inputs: the values the runtime reads, prepared as it documents.
                        std::vector<float> rp(3 * count), rn(3 * count), rd(3 * count);
                        for (size_t i = 0; i < count; ++i) {
                            for (int k = 0; k < 3; ++k) {
                                rp[3 * i + size_t(k)] = position.value(i, k);
                                rn[3 * i + size_t(k)] = normal.value(i, k);
                                rd[3 * i + size_t(k)] =
                                    eyeMode ? eye[k] - rp[3 * i + size_t(k)] : direction.value(i, k);
                            }
                            for (float* v : {&rn[3 * i], &rd[3 * i]}) {
                                if (unit && !(eyeMode && v == &rd[3 * i])) continue;
                                const float len2 = v[0] * v[0] + v[1] * v[1] + v[2] * v[2];
                                const bool ok = len2 > 0.0f && std::isfinite(len2);
                                const float inv = 1.0f / std::sqrt(len2);
                                for (int k = 0; k < 3; ++k)
                                    v[k] = ok ? v[k] * inv : std::numeric_limits<float>::quiet_NaN();
                            }
                        }
                        for (bool shade : {false, true}) {
                            std::vector<float> expected(3 * count);
                            std::vector<uint8_t> expectedFlags(count), flags(count, 0xEE);
                            ASSERT_EQ(asset.evaluateBatch(count, rp.data(), rn.data(), rd.data(), expected.data(),
                                                          expectedFlags.data()),
                                      NRAD_OK);
                            if (shade) {
                                test::shadeReference(source.header.flags, count, rn.data(), rd.data(), surfaces.data(),
                                               expected.data());
                                // nradShadeBatch, which runs the same driver, against the same reference.
                                std::vector<float> batch(3 * count);
                                std::vector<uint8_t> batchFlags(count);
                                ASSERT_EQ(asset.shadeBatch(count, rp.data(), rn.data(), rd.data(), surfaces.data(),
                                                           batch.data(), batchFlags.data()),
                                          NRAD_OK);
                                ASSERT_EQ(batchFlags, expectedFlags);
                                ASSERT_EQ(std::memcmp(batch.data(), expected.data(), 4 * batch.size()), 0);
                            }
                            for (const Output& out : outputs) {
                                const size_t pixel = size_t(out.channels) * (out.half ? 2 : 4),
                                             stride = out.stride ? out.stride : pixel;
                                std::vector<uint8_t> pixels((count - 1) * stride + pixel + 8, 0x5A);
                                NradGBuffer g;
                                std::memset(&g, 0, sizeof g);
                                g.structSize = sizeof g;
                                g.flags =
                                    (unit ? NRAD_GBUFFER_UNIT_VECTORS : 0u) | (eyeMode ? NRAD_GBUFFER_EYE : 0u);
                                g.count = count;
                                g.position = position.describe();
                                g.normal = normal.describe();
                                if (!eyeMode) g.direction = direction.describe();
                                for (int k = 0; k < 3; ++k) g.eye[k] = eye[k];
                                g.surfaces = shade ? surfaces.data() : nullptr;
                                if (shade && !out.half) {  // material terms inside a larger record, an odd stride
                                    g.surfaces = reinterpret_cast<const NradSurface*>(paddedSurfaces.data());
                                    g.surfaceStride = kPaddedSurface;
                                }
                                g.pointFlags = flags.data();
                                g.output = pixels.data();
                                g.outputStride = out.stride;
                                g.outputFormat = out.half ? NRAD_FORMAT_F16 : NRAD_FORMAT_F32;
                                g.outputChannels = uint32_t(out.channels);
                                ASSERT_EQ(nradShadeGBuffer(asset.get(), &g, nullptr, 0), NRAD_OK);
                                ASSERT_EQ(flags, expectedFlags);
                                const std::string where =
                                    "strides " + std::to_string(in.positionStride) + "/" +
                                    std::to_string(in.normalStride) + "/" + std::to_string(in.directionStride) +
                                    " mode " + std::to_string(mode) + " shade " + std::to_string(shade) +
                                    " pixel " + std::to_string(pixel) + "/" + std::to_string(stride);
                                for (size_t i = 0; i < count; ++i) {
                                    const uint8_t* px = &pixels[i * stride];
                                    for (int c = 0; c < out.channels; ++c) {
                                        const float v = c < 3 ? expected[3 * i + size_t(c)] : 1.0f;
                                        if (out.half) {
                                            uint16_t h;
                                            std::memcpy(&h, px + 2 * c, 2);
                                            ASSERT_EQ(h, format::floatToHalf(v))
                                                << where << " point " << i << " channel " << c;
                                        } else {
                                            ASSERT_EQ(std::memcmp(px + 4 * c, &v, 4), 0)
                                                << where << " point " << i << " channel " << c;
                                        }
                                    }
                                    const size_t gap = i + 1 < count ? stride - pixel : 8;
                                    for (size_t b = 0; b < gap; ++b)
                                        ASSERT_EQ(px[pixel + b], 0x5A) << where << ": wrote past pixel " << i;
                                }
                            }
                        }
                    }
            }
        }
        if (kernel != NRAD_KERNEL_SCALAR) {
            EXPECT_GT(rt::testing::gbufferBlocksSoFar(), before) << "the vector path was not taken";
            EXPECT_GT(rt::testing::treeBlocksSoFar(), treeBefore) << "no tree vector was located in registers";
        }
    }
    nradSelectKernel(NRAD_KERNEL_AUTO);
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

// NRAD_GBUFFER_VOLUME (issue 42): receivers that were not in the bake, through the asset's volume networks with the
// normal as their direction, shaded by eval::shadeVolume with the viewer's direction: nradEvaluateVolumeBatch and
// shadeVolume on the same values in fp32, bit for bit; evaluate-only needs no direction.
TEST(GBuffer, TheVolumeQueryMatchesTheVolumeBatchAndShadeVolume) {
    Fixture f(3000);
    nrad::Asset plain;
    {
        const std::vector<uint8_t> bytes = format::encode(f.source);
        ASSERT_EQ(plain.loadFromMemory(bytes.data(), bytes.size()), NRAD_OK);
    }
    std::mt19937 rng(9);
    std::uniform_real_distribution<float> u(-0.6f, 0.6f);
    f.source.volumeVoxels = f.source.voxels;
    for (size_t i = 0; i < f.source.weights.size(); ++i) f.source.volumeWeights.push_back(u(rng));
    const std::vector<uint8_t> bytes = format::encode(f.source);
    ASSERT_EQ(f.asset.loadFromMemory(bytes.data(), bytes.size()), NRAD_OK);
    const size_t count = f.texels.size();
    for (bool eyeMode : {false, true})
        for (bool shade : {false, true}) {
            f.referenceInputs(eyeMode);
            std::vector<float> expected(3 * count), got(3 * count, -1.0f);
            std::vector<uint8_t> expectedFlags(count), flags(count);
            ASSERT_EQ(nradEvaluateVolumeBatch(f.asset.get(), count, f.p.data(), f.n.data(), expected.data(), expectedFlags.data()), NRAD_OK);
            if (shade) test::shadeReference(0, count, f.n.data(), f.d.data(), f.surfaces.data(), expected.data(), true);
            NradGBuffer g = f.describe(eyeMode);
            g.flags |= NRAD_GBUFFER_VOLUME;
            if (!shade && !eyeMode) g.direction = {nullptr, 0, NRAD_FORMAT_F32};  // not read
            if (shade) g.surfaces = f.surfaces.data();
            g.output = got.data();
            g.outputFormat = NRAD_FORMAT_F32;
            g.outputChannels = 3;
            g.pointFlags = flags.data();
            ASSERT_EQ(nradShadeGBuffer(f.asset.get(), &g, nullptr, 0), NRAD_OK);
            for (size_t i = 0; i < 3 * count; ++i)
                ASSERT_EQ(got[i], expected[i]) << "eye " << eyeMode << " shade " << shade << " value " << i;
            EXPECT_EQ(flags, expectedFlags);
            // The same description against the surfaces' networks reads something else, and an asset without
            // volume networks refuses it.
            if (shade) {
                NradGBuffer surfacesOnly = g;
                surfacesOnly.flags &= ~NRAD_GBUFFER_VOLUME;
                std::vector<float> other(3 * count);
                surfacesOnly.output = other.data();
                ASSERT_EQ(nradShadeGBuffer(f.asset.get(), &surfacesOnly, nullptr, 0), NRAD_OK);
                EXPECT_NE(other, got);
            }
            EXPECT_EQ(nradShadeGBuffer(plain.get(), &g, nullptr, 0), NRAD_ERROR_INVALID_ARGUMENT);
        }
}

}  // namespace
}  // namespace nrad
