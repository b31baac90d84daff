// The light in the volume (issue 42): closed forms for a receiver in free space, the asset's VVOX/VWGT round trip.
#include <cmath>
#include <cstdio>
#include <cstring>

#include <gtest/gtest.h>
#include <nrad/eval.h>
#include <nrad/format.h>

#include "baker/bake/baker.h"
#include "baker/nn/random.h"
#include "baker/render/bsdf.h"
#include "baker/scene/gltf_loader.h"
#include "baker/util/maths.h"
#include "support/test_paths.h"
#include "support/test_scenes.h"
#include "support/volume_query.h"

namespace nrad {
namespace {

BakeSettings volumeBake() {
    BakeSettings s;
    s.grid = {2, 2, 2};
    s.samples.points = 4000;
    s.samples.paths = 4;
    s.train.epochs = 300;
    s.volume.enabled = true;
    s.volume.pointsPerCell = 1500;
    s.volume.paths = 8;
    return s;
}

// The scaffold under a uniform sky of radiance L, nothing else lighting it.
Scene skyScaffold(const glm::vec3& L) {
    Scene scene = test::makeScaffold();
    scene.environment.kind = Environment::Kind::Constant;
    scene.environment.color = L;
    return scene;
}

glm::vec3 randomDirection(SplitMix64& r) {
    const float z = 1.0f - 2.0f * r.uniform(), phi = 2.0f * kPi * r.uniform(), s = std::sqrt(1.0f - z * z);
    return {s * std::cos(phi), s * std::sin(phi), z};
}

// RMS of the query's error at random points (inside the cube, away from the corners) and normals, over `scale`.
template <class Expected>
double rmsError(const test::VolumeQuery& query, Expected expected, float scale) {
    SplitMix64 r(42);
    double sum = 0.0;
    const int n = 400;
    for (int i = 0; i < n; ++i) {
        const glm::vec3 p(1.6f * r.uniform() - 0.8f, 1.6f * r.uniform() - 0.8f, 1.6f * r.uniform() - 0.8f);
        const glm::vec3 normal = randomDirection(r);
        const glm::vec3 d = query(p, normal) - expected(normal);
        sum += double(glm::dot(d, d)) / 3.0;
    }
    return std::sqrt(sum / n) / scale;
}

TEST(VolumeLight, AReceiverUnderAUniformSkyScattersItsRadianceAtEveryNormal) {
    const glm::vec3 L(0.5f, 1.0f, 2.0f);
    const Scene scene = skyScaffold(L);
    const BakeResult r = bakeScene(scene, volumeBake());
    ASSERT_EQ(r.asset.volumeVoxels.size(), 8u);  // every cell of the 2 x 2 x 2 grid has free space
    EXPECT_EQ(r.volumeStats.inside, 0u);
    // E(x, n) = pi L for every n: what a white Lambertian receiver scatters is L.
    const test::VolumeQuery query(r.asset);
    const double err = rmsError(query, [&](const glm::vec3&) { return L; }, 1.0f);
    std::printf("uniform sky: rms error %.4f of L's green\n", err);
    EXPECT_LT(err, 0.02) << "rms error over |L| = 1 (the green channel)";
}

// Under a byte budget the cells are a kd-tree's leaves: the budget pays for a volume network per leaf beside the
// surfaces' networks, the asset keeps to it, and the query through the tree keeps the closed form.
TEST(VolumeLight, UnderAByteBudgetTheVolumeNetworksFitAndKeepTheClosedForm) {
    const glm::vec3 L(0.5f, 1.0f, 2.0f);
    const Scene scene = skyScaffold(L);
    BakeSettings s = volumeBake();
    s.partition.budgetBytes = 3 * 1024;
    s.partition.levels = 4;
    s.partition.minLeafSamples = 64;
    const BakeResult r = bakeScene(scene, s);
    const std::vector<uint8_t> bytes = format::encode(r.asset);
    EXPECT_LE(bytes.size(), s.partition.budgetBytes);
    ASSERT_FALSE(r.asset.tree.empty());
    EXPECT_GT(r.asset.leafCount, 2u);
    EXPECT_EQ(r.asset.volumeVoxels.size(), r.asset.leafCount) << "every leaf of the scaffold has free space";
    // The budget held two networks per leaf: without the volume the same budget refines to about twice the leaves.
    BakeSettings plain = s;
    plain.volume.enabled = false;
    const BakeResult without = bakeScene(scene, plain);
    EXPECT_GT(without.asset.leafCount, r.asset.leafCount);
    std::printf("3 KB: %u leaves with the volume's networks, %u without; %zu bytes\n", r.asset.leafCount, without.asset.leafCount,
                bytes.size());
    const test::VolumeQuery query(r.asset);
    const double err = rmsError(query, [&](const glm::vec3&) { return L; }, 1.0f);
    std::printf("uniform sky, kd-tree: rms error %.4f of L's green\n", err);
    EXPECT_LT(err, 0.02);
    EXPECT_TRUE(test::bakeBytes(scene, s, 1) == test::bakeBytes(scene, s, 2));
}

// The directional albedo of the glossy response's receiver (white metal, roughness eval::kGlossyRoughness) at n.v =
// mu, by midpoint quadrature of the BSDF's own value over the hemisphere: under a uniform sky L it reflects L times it.
double glossyReceiverAlbedo(double mu) {
    BsdfParams params;
    params.metallic = 1.0f;
    params.roughness = eval::kGlossyRoughness;
    const Bsdf bsdf(Frame::fromNormal(glm::vec3(0.0f, 0.0f, 1.0f)), params);
    const glm::vec3 wo(float(std::sqrt(std::max(0.0, 1.0 - mu * mu))), 0.0f, float(mu));
    const int n = 192;
    double sum = 0.0;
    for (int i = 0; i < n; ++i) {
        const double c = (i + 0.5) / n, s = std::sqrt(1.0 - c * c);
        for (int j = 0; j < 2 * n; ++j) {
            const double phi = 2.0 * kPi * (j + 0.5) / (2 * n);
            sum += double(bsdf.eval(wo, glm::vec3(float(s * std::cos(phi)), float(s * std::sin(phi)), float(c))).y) * c;
        }
    }
    return sum * (1.0 / n) * (2.0 * kPi / (2 * n));
}

// Under a uniform sky of radiance L the glossy response (the receiver's reflected radiance over its lobe's split-sum
// albedo) is L times the lobe's albedo over that fit, for every normal and viewer; shaded back by shadeVolumeGlossy
// for the same receiver it gives the reflected radiance itself.
TEST(VolumeLight, TheGlossyResponseUnderAUniformSkyIsTheSkyTimesTheLobesAlbedo) {
    const glm::vec3 L(0.5f, 1.0f, 2.0f);
    const Scene scene = skyScaffold(L);
    BakeSettings s = volumeBake();
    s.volume.glossy = true;
    const BakeResult r = bakeScene(scene, s);
    ASSERT_EQ(r.asset.glossyVoxels.size(), 8u);
    std::vector<double> albedo(33);  // at mu = k / 32
    for (size_t k = 0; k < albedo.size(); ++k) albedo[k] = glossyReceiverAlbedo(std::max(1e-3, double(k) / 32.0));
    const test::VolumeQuery glossy(r.asset, true), diffuse(r.asset);
    SplitMix64 rng(9);
    double sum = 0.0, bias = 0.0, roughSame = 0.0, diffuseSum = 0.0;
    const int n = 400;
    for (int i = 0; i < n; ++i) {
        const glm::vec3 p(1.6f * rng.uniform() - 0.8f, 1.6f * rng.uniform() - 0.8f, 1.6f * rng.uniform() - 0.8f);
        const glm::vec3 normal = randomDirection(rng);
        glm::vec3 v = randomDirection(rng);
        if (glm::dot(v, normal) < 0.0f) v = -v;
        const float mu = glm::dot(v, normal);
        const double at = double(mu) * 32.0, f = at - std::floor(at);
        const size_t k = std::min<size_t>(31, size_t(at));
        const double rho = albedo[k] * (1.0 - f) + albedo[k + 1] * f;
        const glm::vec3 expected = L * float(rho / eval::glossyAlbedo(mu));
        const glm::vec3 d = (glossy(p, normal, v) - expected) / expected;  // relative, per channel
        sum += double(glm::dot(d, d)) / 3.0;
        bias += double(d.x + d.y + d.z) / 3.0;
        // Shaded: a rough receiver (roughness 1) exactly as shadeVolume shades it; a white Lambertian one (no
        // specular lobe) reflects D = L.
        const glm::vec3 g = glossy(p, normal, v), dv = diffuse(p, normal);
        eval::Surface rough;
        rough.baseColor[0] = 0.3f;
        rough.metallic = 0.4f;
        float a[3], b[3];
        eval::shadeVolumeGlossy(&dv.x, &g.x, rough, mu, a);
        eval::shadeVolume(&dv.x, rough, mu, b);
        for (int c = 0; c < 3; ++c) roughSame = std::max(roughSame, double(std::abs(a[c] - b[c])) / double(b[c]));
        eval::Surface lambert;
        lambert.specular = 0.0f;
        eval::shadeVolumeGlossy(&dv.x, &g.x, lambert, mu, a);
        diffuseSum += std::pow(double(a[1]) - L.y, 2.0);
    }
    const double err = std::sqrt(sum / n), diffuseErr = std::sqrt(diffuseSum / n);
    bias /= n;
    std::printf("glossy response under a uniform sky: rms relative error %.4f (mean %+.4f); Lambertian receiver %.4f\n", err, bias,
                diffuseErr);
    EXPECT_LT(err, 0.04);  // measured 3.1% rms, a mean of +0.5%; up to 5% at grazing views (the lobe's 8-path targets are noisier than the diffuse ones)
    EXPECT_LT(std::abs(bias), 0.015);
    EXPECT_LT(roughSame, 1e-6) << "at roughness 1 shadeVolumeGlossy is shadeVolume";
    EXPECT_LT(diffuseErr, 0.02) << "a Lambertian receiver takes the diffuse quantity alone";
}

TEST(VolumeLight, AReceiverUnderASunScattersItsIlluminanceTimesTheCosineOverPi) {
    Scene scene = test::makeScaffold();
    PunctualLight sun;
    sun.type = PunctualLight::Type::Directional;
    sun.direction = glm::normalize(glm::vec3(-0.3f, -1.0f, -0.2f));  // the light travels down
    sun.intensity = glm::vec3(3.0f);
    scene.lights.push_back(sun);
    const BakeResult r = bakeScene(scene, volumeBake());
    const test::VolumeQuery query(r.asset);
    const double err = rmsError(
        query, [&](const glm::vec3& n) { return glm::vec3(3.0f * std::max(0.0f, -glm::dot(n, sun.direction)) / kPi); }, 3.0f / kPi);
    std::printf("sun: rms error %.4f of E / pi\n", err);
    EXPECT_LT(err, 0.05) << "rms error over E / pi";
}

// Two rooms sharing a 2 cm wall (x = 2.22 to 2.24 m), room A lit by a panel under its ceiling, room B sealed: a
// receiver anywhere in room B reads room B's light (none), not room A's, though cells of the grid span the wall
// (the wall splits give each side its own cells, the volume's networks too).
TEST(VolumeLight, AReceiverInASealedDarkRoomReadsItsDarknessNotTheLitRoom) {
    Scene scene = loadGltf(test::sourcePath("scenes/sealed-rooms/sealed-rooms.gltf"));
    BakeSettings s;
    s.samples.points = 20000;
    s.samples.paths = 8;
    s.train.epochs = 150;
    s.volume.enabled = true;
    s.volume.pointsPerCell = 300;
    s.volume.paths = 8;
    const BakeResult r = bakeScene(scene, s);
    const test::VolumeQuery query(r.asset);
    SplitMix64 rng(3);
    double lit = 0.0, dark = 0.0, darkest = 0.0;
    const int n = 1000;
    for (int i = 0; i < n; ++i) {
        const glm::vec3 normal = randomDirection(rng);
        const glm::vec3 a(0.2f + 1.8f * rng.uniform(), 0.2f + 2.2f * rng.uniform(), 0.2f + 3.6f * rng.uniform());
        const glm::vec3 b(2.5f + 3.3f * rng.uniform(), 0.2f + 2.2f * rng.uniform(), 0.2f + 3.6f * rng.uniform());
        const glm::vec3 la = query(a, normal), lb = query(b, normal);
        lit += (la.x + la.y + la.z) / (3.0 * n);
        dark += (lb.x + lb.y + lb.z) / (3.0 * n);
        darkest = std::max(darkest, double(std::max(lb.x, std::max(lb.y, lb.z))));
    }
    std::printf("sealed rooms: lit room mean %.4g, dark room mean %.3g, max %.3g\n", lit, dark, darkest);
    EXPECT_GT(lit, 0.05);
    EXPECT_LT(dark, 1e-3 * lit) << "the dark room reads the lit room's light";
    // Measured 5.5% at most, a point by the wall (the exponential output; 1.7% with the linear one), the mean 9.4e-4:
    // the goal is within 10% of the reference.
    EXPECT_LT(darkest, 0.1 * lit);
}

// The volume's noisy targets get the paths that bring their relative standard error to the bound (as the surfaces'
// do, --noisy-paths): some points of the lit room, at most (factor - 1) x paths more each; none with the factor 1.
TEST(VolumeLight, NoisyTargetsGetMorePathsWithinTheBound) {
    Scene scene = loadGltf(test::sourcePath("scenes/sealed-rooms/sealed-rooms.gltf"));
    BakeSettings s;
    s.samples.points = 4000;
    s.samples.paths = 4;
    s.train.epochs = 20;
    s.train.restarts = 1;
    s.volume.enabled = true;
    s.volume.pointsPerCell = 100;
    s.volume.paths = 8;
    s.samples.extraPathsFactor = 4;
    const BakeResult more = bakeScene(scene, s);
    s.samples.extraPathsFactor = 1;
    const BakeResult none = bakeScene(scene, s);
    std::printf("volume: %llu of %llu points noisy, %llu extra paths\n", (unsigned long long)more.volumeStats.noisyPoints,
                (unsigned long long)(more.volumeStats.tried - more.volumeStats.inside), (unsigned long long)more.volumeStats.extraPaths);
    EXPECT_GT(more.volumeStats.noisyPoints, 0u);
    EXPECT_LT(more.volumeStats.noisyPoints, more.volumeStats.tried - more.volumeStats.inside);  // the dark room's are exact
    EXPECT_GE(more.volumeStats.extraPaths, more.volumeStats.noisyPoints);
    EXPECT_LE(more.volumeStats.extraPaths, more.volumeStats.noisyPoints * 3u * 8u);
    EXPECT_GT(more.volumeStats.rays, none.volumeStats.rays);
    EXPECT_EQ(none.volumeStats.noisyPoints, 0u);
    EXPECT_EQ(none.volumeStats.extraPaths, 0u);
}

TEST(VolumeLight, TheAssetCarriesTheVolumeNetworks) {
    const Scene scene = skyScaffold(glm::vec3(1.0f));
    BakeSettings s = volumeBake();
    s.volume.pointsPerCell = 100;
    s.train.epochs = 20;
    const BakeResult r = bakeScene(scene, s);
    const std::vector<uint8_t> bytes = format::encode(r.asset);
    format::Asset back;
    ASSERT_EQ(format::decode(bytes.data(), bytes.size(), back), format::DecodeStatus::Ok);
    // The volume's networks decode exponentially (symmetric-relative-exp), the surfaces' as TOPO says: flag bit 4,
    // version 2.6.
    EXPECT_EQ(bytes[10], 6u) << "an asset with exponential volume networks is version 2.6";
    EXPECT_TRUE(back.header.flags & format::kFlagVolumeExponential);
    EXPECT_EQ(back.volumeTransform(), format::OutputTransform::Exponential);
    EXPECT_EQ(back.topology.outputTransform, format::OutputTransform::ClampedLinear);
    for (const format::VoxelEntry& v : back.volumeVoxels) EXPECT_GT(v.scale, 0.0f);
    ASSERT_EQ(back.volumeVoxels.size(), r.asset.volumeVoxels.size());
    for (size_t k = 0; k < back.volumeVoxels.size(); ++k) EXPECT_EQ(back.volumeVoxels[k].index, r.asset.volumeVoxels[k].index);
    EXPECT_EQ(bytes.size(), format::encodedSize(back.topology, back.voxels.size(), 0, back.metadata.size(), back.volumeVoxels.size()));
    // Without them, the bytes of before (version 2.1: blended).
    s.volume.enabled = false;
    const std::vector<uint8_t> plain = format::encode(bakeScene(scene, s).asset);
    EXPECT_EQ(plain[10], 1u);
    format::Asset noVolume;
    ASSERT_EQ(format::decode(plain.data(), plain.size(), noVolume), format::DecodeStatus::Ok);
    EXPECT_TRUE(noVolume.volumeVoxels.empty());
    EXPECT_FALSE(noVolume.header.flags & format::kFlagVolumeExponential);
    // The flag without volume networks is refused.
    {
        format::Asset flagged = noVolume;
        flagged.header.flags |= format::kFlagVolumeExponential;
        const std::vector<uint8_t> flaggedBytes = format::encodeUnchecked(flagged);
        format::Asset refused;
        EXPECT_EQ(format::decode(flaggedBytes.data(), flaggedBytes.size(), refused), format::DecodeStatus::BadVolume);
    }
    // VVOX without VWGT is refused: VWGT's type renamed to one this version does not know (and the CRCs fixed).
    std::vector<uint8_t> bad = bytes;
    const uint32_t sections = uint32_t(bad[20]) | uint32_t(bad[21]) << 8;
    bool renamed = false;
    for (uint32_t i = 0; i < sections; ++i) {
        uint8_t* record = bad.data() + format::kHeaderSize + i * format::kSectionRecordSize;
        if (std::memcmp(record, "VWGT", 4) == 0) {
            std::memcpy(record, "XWGT", 4);
            renamed = true;
        }
    }
    ASSERT_TRUE(renamed);
    auto put32 = [&](size_t at, uint32_t v) {
        for (int k = 0; k < 4; ++k) bad[at + size_t(k)] = uint8_t(v >> (8 * k));
    };
    put32(40, format::crc32(bad.data() + format::kHeaderSize, sections * format::kSectionRecordSize));
    put32(60, format::crc32(bad.data(), 60));
    format::Asset out;
    EXPECT_EQ(format::decode(bad.data(), bad.size(), out), format::DecodeStatus::BadVolume);
    // VVOX and VWGT of different sizes are refused too.
    format::Asset broken = back;
    broken.volumeWeights.resize(broken.volumeWeights.size() / 2);
    const std::vector<uint8_t> mismatched = format::encodeUnchecked(broken);
    EXPECT_EQ(format::decode(mismatched.data(), mismatched.size(), out), format::DecodeStatus::BadVolume);
    // The same bytes whatever the threads.
    s.volume.enabled = true;
    EXPECT_TRUE(test::bakeBytes(scene, s, 1) == test::bakeBytes(scene, s, 2));
    // With the glossy response (2.5, here 2.6 for the flag): its networks round trip, and the diffuse ones keep their bytes.
    s.volume.glossy = true;
    const BakeResult g = bakeScene(scene, s);
    const std::vector<uint8_t> glossyBytes = format::encode(g.asset);
    EXPECT_EQ(glossyBytes[10], 6u);
    format::Asset glossyBack;
    ASSERT_EQ(format::decode(glossyBytes.data(), glossyBytes.size(), glossyBack), format::DecodeStatus::Ok);
    ASSERT_EQ(glossyBack.glossyVoxels.size(), g.asset.glossyVoxels.size());
    EXPECT_EQ(glossyBack.volumeWeights, back.volumeWeights) << "the glossy response changed the diffuse volume";
    EXPECT_EQ(glossyBytes.size(), format::encodedSize(glossyBack.topology, glossyBack.voxels.size(), 0, glossyBack.metadata.size(),
                                                      glossyBack.volumeVoxels.size(), glossyBack.glossyVoxels.size()));
    EXPECT_TRUE(test::bakeBytes(scene, s, 1) == test::bakeBytes(scene, s, 2));
    // A glossy response without the volume's networks, or with weights of another count, is refused.
    format::Asset lone = glossyBack;
    lone.volumeVoxels.clear();
    lone.volumeWeights.clear();
    const std::vector<uint8_t> loneBytes = format::encodeUnchecked(lone);
    EXPECT_EQ(format::decode(loneBytes.data(), loneBytes.size(), out), format::DecodeStatus::BadVolume);
    format::Asset halved = glossyBack;
    halved.glossyWeights.resize(halved.glossyWeights.size() / 2);
    const std::vector<uint8_t> halvedBytes = format::encodeUnchecked(halved);
    EXPECT_EQ(format::decode(halvedBytes.data(), halvedBytes.size(), out), format::DecodeStatus::BadVolume);
}

}  // namespace
}  // namespace nrad
