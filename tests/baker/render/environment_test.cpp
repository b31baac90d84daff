// The environment light: its mapping, its importance sampler (chi-square against the pdf it claims, and its
// estimate against uniform sphere sampling and the closed form), and closed-form scenes under a sky: a convex
// white Lambertian object of albedo a under a uniform sky of radiance 1 reflects exactly a; a Lambertian
// plane under a map reflects (a / pi) x the map's cosine-weighted integral over its hemisphere. Maps are
// generated here (.exr through OpenEXR, .hdr written as Radiance RGBE), never downloaded.
#include <cmath>
#include <cstdio>
#include <cstring>
#include <limits>
#include <filesystem>
#include <fstream>
#include <random>

#include <gtest/gtest.h>

#include "baker/render/accel.h"
#include "baker/lights/environment_light.h"
#include "baker/render/image_io.h"
#include "baker/lights/light_sampler.h"
#include "baker/render/path_tracer.h"
#include "baker/scene/gltf_loader.h"
#include "baker/util/threads.h"
#include "support/test_scenes.h"

namespace nrad {
namespace {

constexpr double kPi = 3.14159265358979323846;

// A 32 x 16 map: a dim blue-ish gradient sky, a dark ground half and a small sun-like hot spot (stiff: the
// spot is 2,000x the sky).
Environment makeMap(float rotation = 0.0f) {
    Environment e;
    e.kind = Environment::Kind::Map;
    e.width = 32;
    e.height = 16;
    e.rotationDegrees = rotation;
    e.source = "<generated>";
    e.texels.resize(size_t(e.width) * size_t(e.height));
    for (int y = 0; y < e.height; ++y)
        for (int x = 0; x < e.width; ++x) {
            glm::vec3 c = y < e.height / 2 ? glm::vec3(0.3f, 0.5f, 1.0f) * (1.0f - float(y) / float(e.height))
                                           : glm::vec3(0.05f, 0.04f, 0.03f);
            if (x == 20 && y == 4) c = glm::vec3(2000.0f, 1800.0f, 1500.0f);
            e.texels[size_t(y) * size_t(e.width) + size_t(x)] = c;
        }
    return e;
}

// Radiance RGBE (.hdr), flat scanlines.
void writeHdr(const std::string& path, const Environment& e) {
    std::ofstream f(path, std::ios::binary);
    f << "#?RADIANCE\nFORMAT=32-bit_rle_rgbe\n\n-Y " << e.height << " +X " << e.width << "\n";
    for (const glm::vec3& t : e.texels) {
        float m = std::max(t.x, std::max(t.y, t.z));
        unsigned char rgbe[4] = {0, 0, 0, 0};
        if (m > 1e-32f) {
            int ex;
            float scale = std::frexp(m, &ex) * 256.0f / m;
            rgbe[0] = (unsigned char)(t.x * scale);
            rgbe[1] = (unsigned char)(t.y * scale);
            rgbe[2] = (unsigned char)(t.z * scale);
            rgbe[3] = (unsigned char)(ex + 128);
        }
        f.write(reinterpret_cast<const char*>(rgbe), 4);
    }
}

TEST(Environment, MappingRoundTripsAndFollowsTheConvention) {
    Environment e = makeMap(37.0f);
    for (float u : {0.01f, 0.3f, 0.5f, 0.77f, 0.99f})
        for (float v : {0.02f, 0.25f, 0.5f, 0.9f}) {
            glm::vec3 d = e.direction({u, v});
            EXPECT_NEAR(glm::length(d), 1.0f, 1e-6f);
            glm::vec2 uv = e.mapCoordinates(d);
            EXPECT_NEAR(uv.x, u, 1e-5f);
            EXPECT_NEAR(uv.y, v, 1e-5f);
        }
    Environment plain = makeMap();
    // The top row is straight up, the centre column towards -Z, u grows towards +X.
    EXPECT_NEAR(plain.mapCoordinates({0, 1, 0}).y, 0.0f, 1e-6f);
    glm::vec2 front = plain.mapCoordinates({0, 0, -1});
    EXPECT_NEAR(front.x, 0.5f, 1e-6f);
    EXPECT_NEAR(front.y, 0.5f, 1e-6f);
    EXPECT_NEAR(plain.mapCoordinates({1, 0, 0}).x, 0.75f, 1e-6f);
    // Rotating by 90 degrees counter-clockwise seen from above brings what was towards -Z to -X.
    Environment rotated = makeMap(90.0f);
    EXPECT_EQ(rotated.radiance({-1, 0.3f, 0}), plain.radiance(glm::normalize(glm::vec3(0, 0.3f, -1))));
}

TEST(Environment, ParsesColoursAndRefusesBadValuesAndFiles) {
    Environment c = parseEnvironment("0.5,1,2", 2.0f, 0.0f);
    EXPECT_EQ(c.kind, Environment::Kind::Constant);
    EXPECT_EQ(c.radiance({0, 1, 0}), glm::vec3(1.0f, 2.0f, 4.0f));
    EXPECT_FALSE(parseEnvironment("none").active());
    EXPECT_FALSE(parseEnvironment("0,0,0").active());
    EXPECT_THROW(parseEnvironment("1,-1,1"), EnvironmentSpecError);  // a flag value: exit 2, not 3
    EXPECT_THROW(parseEnvironment("1,nan,1"), EnvironmentSpecError);
    EXPECT_THROW(parseEnvironment("/no/such/sky.exr"), SceneError);
    const std::string dir = testing::TempDir();
    std::ofstream(dir + "/not-an-image.hdr") << "hello";
    EXPECT_THROW(parseEnvironment(dir + "/not-an-image.hdr"), SceneError);
    std::ofstream(dir + "/sky.png") << "hello";
    EXPECT_THROW(parseEnvironment(dir + "/sky.png"), SceneError);
    // A non-finite texel is an error naming the texel, not clamped.
    Image bad(4, 2);
    bad.at(3, 1) = glm::vec3(std::numeric_limits<float>::infinity(), 0, 0);
    writeExr(dir + "/bad.exr", bad);
    try {
        parseEnvironment(dir + "/bad.exr");
        ADD_FAILURE() << "accepted an infinite texel";
    } catch (const SceneError& e) {
        EXPECT_NE(std::string(e.what()).find("texel (3, 1)"), std::string::npos) << e.what();
    }
}

TEST(Environment, ExrAndHdrMapsLoadAsWritten) {
    Environment e = makeMap();
    const std::string dir = testing::TempDir();
    Image img(e.width, e.height);
    img.pixels = e.texels;
    writeExr(dir + "/sky.exr", img);
    Environment exr = parseEnvironment(dir + "/sky.exr", 1.5f, 10.0f);
    ASSERT_EQ(exr.kind, Environment::Kind::Map);
    ASSERT_EQ(exr.width, 32);
    ASSERT_EQ(exr.height, 16);
    EXPECT_EQ(exr.texels, e.texels);
    EXPECT_EQ(exr.intensity, 1.5f);
    writeHdr(dir + "/sky.hdr", e);
    Environment hdr = parseEnvironment(dir + "/sky.hdr");
    ASSERT_EQ(hdr.width, 32);
    ASSERT_EQ(hdr.height, 16);
    // RGBE keeps 8 bits of mantissa under the texel's largest channel.
    for (size_t i = 0; i < e.texels.size(); ++i) {
        const float step = std::max(e.texels[i].x, std::max(e.texels[i].y, e.texels[i].z)) / 128.0f;
        for (int k = 0; k < 3; ++k) EXPECT_NEAR(hdr.texels[i][k], e.texels[i][k], step) << i;
    }
}

// Samples land in texels with the frequencies the sampler's pdf claims (chi-square over every texel), and
// pdf() of a sampled direction is the pdf sample() reported.
TEST(EnvironmentSampler, SamplesFollowTheirPdf) {
    Environment e = makeMap(25.0f);
    EnvironmentSampler sampler(e);
    ASSERT_TRUE(sampler.active());
    const int W = e.width, H = e.height;
    // Expected probability of each texel: the pdf integrated over it (fine quadrature in u, v).
    std::vector<double> expected(size_t(W * H), 0.0);
    const int sub = 8;
    for (int y = 0; y < H; ++y)
        for (int x = 0; x < W; ++x)
            for (int j = 0; j < sub; ++j)
                for (int i = 0; i < sub; ++i) {
                    glm::vec2 uv((float(x) + (float(i) + 0.5f) / sub) / float(W), (float(y) + (float(j) + 0.5f) / sub) / float(H));
                    double sinTheta = std::sin(kPi * uv.y);
                    expected[size_t(y * W + x)] += sampler.pdf(e.direction(uv)) * 2.0 * kPi * kPi * sinTheta / (double(W) * H * sub * sub);
                }
    double total = 0.0;
    for (double p : expected) total += p;
    EXPECT_NEAR(total, 1.0, 2e-3);

    const int N = 400000;
    std::vector<int> counts(size_t(W * H), 0);
    std::mt19937 rng(7);
    std::uniform_real_distribution<float> uni(0.0f, 1.0f);
    int pdfMismatch = 0;
    for (int n = 0; n < N; ++n) {
        float pdf;
        glm::vec3 L;
        glm::vec3 d = sampler.sample({uni(rng), uni(rng)}, pdf, L);
        ASSERT_GT(pdf, 0.0f);
        ASSERT_NEAR(glm::length(d), 1.0f, 1e-5f);
        glm::vec2 uv = e.mapCoordinates(d);
        int x = std::min(W - 1, int(uv.x * float(W))), y = std::min(H - 1, int(uv.y * float(H)));
        ++counts[size_t(y * W + x)];
        if (std::abs(sampler.pdf(d) / pdf - 1.0f) > 1e-3f) ++pdfMismatch;
    }
    EXPECT_LE(pdfMismatch, N / 1000) << "pdf(sample) differs from the sampled pdf (texel edges only)";
    double chi2 = 0.0;
    int dof = 0;
    for (size_t i = 0; i < counts.size(); ++i) {
        double ex = expected[i] * N;
        if (ex < 5.0) continue;  // the chi-square approximation needs populated bins
        chi2 += (counts[i] - ex) * (counts[i] - ex) / ex;
        ++dof;
    }
    ASSERT_GT(dof, 100);
    EXPECT_LT(chi2, dof + 5.0 * std::sqrt(2.0 * dof)) << "dof " << dof;
}

// The importance-sampled estimate of the integral of the radiance over the sphere agrees with uniform sphere
// sampling and with the closed form 4 pi x meanRadiance().
TEST(EnvironmentSampler, EstimateMatchesUniformSphereSamplingAndClosedForm) {
    Environment e = makeMap(-60.0f);
    e.intensity = 0.5f;
    EnvironmentSampler sampler(e);
    const glm::dvec3 exact = 4.0 * kPi * glm::dvec3(e.meanRadiance());
    std::mt19937 rng(3);
    std::uniform_real_distribution<float> uni(0.0f, 1.0f);
    glm::dvec3 importance(0.0), uniform(0.0);
    const int N = 1 << 20;
    for (int n = 0; n < N; ++n) {
        float pdf;
        glm::vec3 L;
        sampler.sample({uni(rng), uni(rng)}, pdf, L);
        importance += glm::dvec3(L) / double(pdf);
        float z = 1.0f - 2.0f * uni(rng), r = std::sqrt(std::max(0.0f, 1.0f - z * z)), phi = float(2.0 * kPi) * uni(rng);
        uniform += glm::dvec3(e.radiance({r * std::cos(phi), z, r * std::sin(phi)})) * (4.0 * kPi);
    }
    importance /= double(N);
    uniform /= double(N);
    for (int k = 0; k < 3; ++k) {
        EXPECT_NEAR(importance[k] / exact[k], 1.0, 0.002) << k;  // almost zero variance: L / pdf is nearly constant
        EXPECT_NEAR(uniform[k] / exact[k], 1.0, 0.03) << k;  // the hot spot makes uniform sampling noisy
    }
}

Image renderScene(const Scene& scene, int size, int spp, int maxDepth = 0, uint32_t seed = 1) {
    return test::renderPathTraced(scene, size, spp, maxDepth, seed, 16);
}

Material lambertian(float albedo) {
    Material m;
    m.baseColor = glm::vec3(albedo);
    m.metallic = 0.0f;
    m.specular = 0.0f;
    return m;
}

// A convex white Lambertian object of albedo a under a uniform sky of radiance 1 reflects exactly a: every
// direction above a point of it is sky. Seen from outside; pixels off the object see the sky (1).
TEST(EnvironmentScenes, ConvexLambertianUnderUniformSkyReflectsItsAlbedo) {
    ThreadScope threads(0);
    for (float a : {0.3f, 0.8f}) {
        Scene scene = test::makeSphereFurnace(lambertian(a), 1.0f, 32);
        scene.cameras[0].position = glm::vec3(0, 0, 4);
        scene.cameras[0].yfov = 0.7f;
        scene.environment = defaultSky();
        Image image = renderScene(scene, 32, 1024);
        // Pixels well inside the sphere's silhouette (radius 1 at distance 4: about 0.5 rad across) and the corners.
        double inside = 0.0;
        int n = 0;
        for (int y = 12; y < 20; ++y)
            for (int x = 12; x < 20; ++x) {
                for (int k = 0; k < 3; ++k) ASSERT_NEAR(image.at(x, y)[k], a, 0.03 * a) << x << "," << y;
                inside += image.at(x, y).x;
                ++n;
            }
        EXPECT_NEAR(inside / n, a, 0.004 * a) << "albedo " << a;
        EXPECT_EQ(image.at(0, 0), glm::vec3(1.0f));
        EXPECT_EQ(image.at(31, 31), glm::vec3(1.0f));
    }
}

// A Lambertian plane (normal +Z) under a map: L = (a / pi) x integral over the upper hemisphere of L_env cos,
// computed by quadrature over the texels. Exercises NEE from the map, BSDF sampling and their MIS weights.
TEST(EnvironmentScenes, LambertianPlaneUnderAMapMatchesQuadrature) {
    ThreadScope threads(0);
    const float a = 0.7f;
    Scene scene = test::makeLitPlane(a, 10.0f);
    scene.environment = makeMap(70.0f);
    const Environment& e = scene.environment;
    glm::dvec3 E(0.0);
    const int sub = 16;
    for (int y = 0; y < e.height; ++y)
        for (int x = 0; x < e.width; ++x)
            for (int j = 0; j < sub; ++j)
                for (int i = 0; i < sub; ++i) {
                    glm::vec2 uv((float(x) + (float(i) + 0.5f) / sub) / float(e.width),
                                 (float(y) + (float(j) + 0.5f) / sub) / float(e.height));
                    glm::vec3 d = e.direction(uv);
                    if (d.z <= 0.0f) continue;
                    double dOmega = 2.0 * kPi * kPi * std::sin(kPi * uv.y) / (double(e.width) * e.height * sub * sub);
                    E += glm::dvec3(e.texels[size_t(y * e.width + x)]) * double(d.z) * dOmega;
                }
    const glm::dvec3 expected = double(a) / kPi * E;
    Image image = renderScene(scene, 8, 4096);
    glm::dvec3 mean = image.mean();
    for (int k = 0; k < 3; ++k) EXPECT_NEAR(mean[k] / expected[k], 1.0, 0.01) << k;
}

// Byte-identical images for 1 and 2 threads with a map, and a different seed changes them.
TEST(EnvironmentScenes, RendersAreIndependentOfThreadCount) {
    Scene scene = test::makeSphereFurnace(lambertian(0.5f), 1.0f, 16);
    scene.cameras[0].position = glm::vec3(0, 0.5f, 3);
    scene.environment = makeMap(15.0f);
    Image one, two;
    {
        ThreadScope t(1);
        one = renderScene(scene, 24, 16);
    }
    {
        ThreadScope t(2);
        two = renderScene(scene, 24, 16);
    }
    ASSERT_EQ(one.pixels.size(), two.pixels.size());
    EXPECT_EQ(0, std::memcmp(one.pixels.data(), two.pixels.data(), one.pixels.size() * sizeof(glm::vec3)));
    Image other = renderScene(scene, 24, 16, 0, 2);
    EXPECT_NE(0, std::memcmp(one.pixels.data(), other.pixels.data(), one.pixels.size() * sizeof(glm::vec3)));
}

// The environment is one light among the others: picked in proportion to its power (4 pi^2 R^2 x mean
// luminance), its own group for light selection, contributing everywhere.
TEST(EnvironmentScenes, IsALightOfItsOwn) {
    Scene scene = test::makeLitPlane(0.5f);
    PunctualLight sun;
    sun.type = PunctualLight::Type::Directional;
    sun.direction = glm::vec3(0, 0, -1);
    sun.intensity = glm::vec3(3.0f);
    scene.lights.push_back(sun);
    scene.environment = parseEnvironment("1,1,1");
    LightSampler lights(scene);
    ASSERT_EQ(lights.lightCount(), 2u);
    ASSERT_EQ(lights.groupCount(), 2u);
    ASSERT_EQ(lights.environmentGroup(), 1);
    const double R = scene.bounds.radius();
    const double envPower = 4.0 * kPi * kPi * R * R, sunPower = kPi * R * R * 3.0;
    EXPECT_NEAR(lights.pickProbability(1), envPower / (envPower + sunPower), 1e-5);
    EXPECT_TRUE(lights.groupCanContribute(1, glm::vec3(0.0f), glm::vec3(0, 0, 1)));
    EXPECT_NEAR(lights.pdfEnvironment(glm::vec3(0, 0, 1)), lights.pickProbability(1) / (4.0 * kPi), 1e-6);
    EXPECT_NEAR(lights.pdfEnvironmentInGroup(glm::vec3(0, 0, 1)), 1.0 / (4.0 * kPi), 1e-6);
    // Without an environment there is no such group and its pdf is zero.
    scene.environment = Environment{};
    LightSampler none(scene);
    EXPECT_EQ(none.environmentGroup(), -1);
    EXPECT_EQ(none.pdfEnvironment(glm::vec3(0, 0, 1)), 0.0f);
}

}  // namespace
}  // namespace nrad

namespace nrad {
namespace {

// A soft sun (a disk of uniform radiance E / (pi sin^2 alpha)) whose cap lies wholly above a Lambertian plane
// gives it the irradiance E cos(beta), beta the angle of the disk's centre from the normal: the radiance is
// (a / pi) E cos(beta), with NEE over the disk's cone and BSDF rays that meet the disk weighted by MIS.
TEST(EnvironmentScenes, SoftSunOnAPlaneMatchesTheClosedForm) {
    ThreadScope threads(0);
    const float a = 0.6f, E = 3.0f;
    for (float alphaDeg : {0.53f, 5.0f, 20.0f}) {
        Scene scene = test::makeLitPlane(a, 10.0f);
        PunctualLight sun;
        sun.type = PunctualLight::Type::Directional;
        const float beta = float(kPi / 6.0);
        sun.direction = -glm::vec3(std::sin(beta), 0.0f, std::cos(beta));
        sun.intensity = glm::vec3(E);
        sun.cosAngularRadius = std::cos(0.5f * alphaDeg * float(kPi) / 180.0f);
        scene.lights.push_back(sun);
        Image image = renderScene(scene, 8, 1024);
        const double expected = a / kPi * E * std::cos(beta);
        EXPECT_NEAR(image.mean().x / expected, 1.0, 0.01) << alphaDeg;
        // The disk is seen directly by a camera ray that points into it.
        EXPECT_NEAR(skyRadiance(scene, -sun.direction).x, E / (kPi * (1.0 - double(sun.cosAngularRadius) * sun.cosAngularRadius)),
                    1e-3 * E / (kPi * (1.0 - double(sun.cosAngularRadius) * sun.cosAngularRadius)));
    }
}

}  // namespace
}  // namespace nrad
