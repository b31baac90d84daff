// Furnace tests: inside a closed sphere with uniform emission Le and diffuse albedo a, the radiance
// everywhere is Le / (1 - a) (unbounded path length); with a path length of 2 it is Le (1 + E(wo)),
// E the directional albedo of the BSDF; punctual lights over a Lambertian plane give (a/pi) E cos.
#include <cmath>
#include <cstdio>

#include <gtest/gtest.h>

#include "baker/render/accel.h"
#include "baker/render/bsdf.h"
#include "baker/lights/light_sampler.h"
#include "baker/render/path_tracer.h"
#include "baker/render/surface.h"
#include "baker/util/threads.h"
#include "support/test_scenes.h"

namespace nrad {
namespace {

constexpr double kPi = 3.14159265358979323846;

Image renderScene(const Scene& scene, int size, int spp, int maxDepth, uint32_t seed = 1) {
    return test::renderPathTraced(scene, size, spp, maxDepth, seed, 1);
}

Material diffuseEmitter(float albedo, glm::vec3 Le) {
    Material m;
    m.baseColor = glm::vec3(albedo);
    m.metallic = 0.0f;
    m.specular = 0.0f;  // pure Lambertian
    m.emission = Le;
    return m;
}

// Every pixel within `pixelTol` and the image mean within `meanTol` (relative) of `expected`.
void expectUniform(const Image& image, glm::vec3 expected, double pixelTol, double meanTol) {
    glm::dvec3 mean = image.mean();
    for (int k = 0; k < 3; ++k) EXPECT_NEAR(mean[k] / expected[k], 1.0, meanTol) << "channel " << k;
    for (int y = 0; y < image.height; ++y)
        for (int x = 0; x < image.width; ++x)
            for (int k = 0; k < 3; ++k)
                ASSERT_NEAR(image.at(x, y)[k] / expected[k], 1.0, pixelTol) << "pixel " << x << "," << y << " channel " << k;
}

// A uniformly random point of the furnace's sphere (radius 1, around the origin), seen from its centre.
bool pointOnTheSphere(const Scene& scene, const Accel& accel, Sampler& sampler, SurfaceInteraction& si) {
    glm::vec2 u = sampler.get2D();
    const float z = 1.0f - 2.0f * u.x, r = std::sqrt(std::max(0.0f, 1.0f - z * z)), phi = 6.2831853f * u.y;
    const glm::vec3 d(r * std::cos(phi), r * std::sin(phi), z);
    Hit hit = accel.intersect(glm::vec3(0.0f), d);
    if (!hit.valid()) return false;
    si = makeInteraction(scene, hit, d);
    return true;
}

class DiffuseFurnace : public ::testing::TestWithParam<float> {};

TEST_P(DiffuseFurnace, RadianceIsLeOverOneMinusAlbedo) {
    ThreadScope threads(0);
    float a = GetParam();
    glm::vec3 Le(0.5f, 1.0f, 2.0f);
    Scene scene = test::makeSphereFurnace(diffuseEmitter(a, Le));
    // 4x4 pixels at 2^18 samples each: the per-pixel standard error is below 0.2% for a <= 0.9.
    Image image = renderScene(scene, 4, 1 << 18, 0);
    expectUniform(image, Le / (1.0f - a), 0.01, 0.01);
}

INSTANTIATE_TEST_SUITE_P(Albedo, DiffuseFurnace, ::testing::Values(0.5f, 0.9f),
                         [](const ::testing::TestParamInfo<float>& param) {
                             return "a" + std::to_string(int(std::lround(param.param * 100)));
                         });

TEST(Furnace, PathLengthOneIsEmissionOnly) {
    glm::vec3 Le(3.0f, 2.0f, 1.0f);
    Scene scene = test::makeSphereFurnace(diffuseEmitter(0.9f, Le));
    Image image = renderScene(scene, 8, 4, 1);
    expectUniform(image, Le, 1e-6, 1e-6);
}

TEST(Furnace, PathLengthTwoIsOneBounceOfTheLobe) {
    // L = Le (1 + E(wo)) at normal incidence; E computed by quadrature of the BSDF itself, so this checks
    // that the path tracer's NEE + MIS integrate the lobe correctly (diffuse, rough and glossy metal).
    struct Lobe {
        float metallic, roughness, specular;
    };
    for (Lobe lobe : {Lobe{0.0f, 1.0f, 0.0f}, Lobe{1.0f, 1.0f, 1.0f}, Lobe{1.0f, 0.5f, 1.0f}, Lobe{0.0f, 0.4f, 1.0f}}) {
        Material m;
        m.baseColor = glm::vec3(0.8f);
        m.metallic = lobe.metallic;
        m.roughness = lobe.roughness;
        m.specular = lobe.specular;
        m.emission = glm::vec3(1.0f);
        Scene scene = test::makeSphereFurnace(m, 1.0f, 128);
        BsdfParams p;
        p.baseColor = m.baseColor;
        p.metallic = m.metallic;
        p.roughness = m.roughness;
        p.specular = m.specular;
        Bsdf bsdf(Frame::fromNormal({0, 0, 1}), p);
        double e = 0.0;
        const int n = 1024;
        for (int i = 0; i < n; ++i) {
            double ct = (i + 0.5) / n, st = std::sqrt(1 - ct * ct);
            for (int j = 0; j < 2 * n; ++j) {
                double phi = 2 * kPi * (j + 0.5) / (2 * n);
                e += bsdf.eval({0, 0, 1}, glm::vec3(float(st * std::cos(phi)), float(st * std::sin(phi)), float(ct))).x * ct;
            }
        }
        e *= (1.0 / n) * (2 * kPi / (2 * n));
        // Only the central pixels: there the view direction is within a few degrees of the normal.
        Image image = renderScene(scene, 2, 1 << 16, 2);
        glm::dvec3 mean = image.mean();
        EXPECT_NEAR(mean.x, 1.0 + e, 0.01 * (1.0 + e))
            << "metallic " << lobe.metallic << " roughness " << lobe.roughness << " specular " << lobe.specular;
    }
}

// Training within the integral equation: one (or two) bounce(s) of NEE and BSDF sampling with a tail standing
// in for the rest of the path. In the furnace with a constant tail T (the scattered radiance it claims at every
// vertex) the estimate's mean is a (Le + T) for one bounce and a (Le + a (Le + T)) for two, whatever T: the
// emission found by NEE and by the BSDF sample adds up to Le once (MIS), the tail is added once at the cut.
TEST(Furnace, ScatteredRadianceWithATailIsOneBounceOfIt) {
    ThreadScope threads(1);
    const float a = 0.7f;
    const glm::vec3 Le(0.5f, 1.0f, 2.0f), T(3.0f, 0.25f, 1.0f);
    Scene scene = test::makeSphereFurnace(diffuseEmitter(a, Le));
    Accel accel(scene);
    LightSampler lights(scene);
    PathTracer tracer(scene, accel, lights);
    const ScatteredRadiance tail = [&](const SurfaceInteraction&) { return T; };
    for (int bounces : {1, 2}) {
        glm::dvec3 sum(0.0);
        RayCounters counters;
        const int n = 1 << 17;
        for (int i = 0; i < n; ++i) {
            Sampler sampler(0x5eedu, uint32_t(i));
            SurfaceInteraction si;
            ASSERT_TRUE(pointOnTheSphere(scene, accel, sampler, si));
            sum += glm::dvec3(tracer.scatteredRadiance(si, sampler, bounces, tail, counters));
        }
        const glm::dvec3 mean = sum / double(n);
        const glm::dvec3 once = double(a) * (glm::dvec3(Le) + glm::dvec3(T));
        const glm::dvec3 expected = bounces == 1 ? once : double(a) * (glm::dvec3(Le) + once);
        for (int k = 0; k < 3; ++k) EXPECT_NEAR(mean[k] / expected[k], 1.0, 0.005) << bounces << " bounce(s), channel " << k;
        // Rays: one shadow ray per vertex before the cut and one extension ray per bounce, at most.
        EXPECT_LE(counters.total(), uint64_t(2 * bounces) * uint64_t(n));
    }
}

// Russian roulette with a throughput threshold (training targets) is as unbiased as the renders' (threshold 1)
// and, in a bright closed scene, far less noisy per path: at a = 0.95 each path estimate of Le / (1 - a) = 20
// has a standard deviation of about 20 with threshold 1 (geometric path lengths at weight 1) and a few with
// 0.1 (the first ~45 bounces summed, only the rest sampled at weight 0.1).
TEST(Furnace, RouletteThresholdIsUnbiasedAndCutsTheVariance) {
    ThreadScope threads(1);
    const float a = 0.95f;
    Scene scene = test::makeSphereFurnace(diffuseEmitter(a, glm::vec3(1.0f)));
    Accel accel(scene);
    LightSampler lights(scene);
    PathTracer tracer(scene, accel, lights);
    double sd[2] = {0.0, 0.0};
    uint64_t rays[2] = {0, 0};
    const float thresholds[2] = {1.0f, 0.1f};
    for (int k = 0; k < 2; ++k) {
        tracer.setRouletteThreshold(thresholds[k]);
        double sum = 0.0, sum2 = 0.0;
        RayCounters counters;
        const int n = 1 << 15;
        for (int i = 0; i < n; ++i) {
            Sampler sampler(0x5eedu, uint32_t(i));
            SurfaceInteraction si;
            ASSERT_TRUE(pointOnTheSphere(scene, accel, sampler, si));
            const double L = tracer.outgoingRadiance(si, sampler, 0, counters).x;
            sum += L;
            sum2 += L * L;
        }
        const double mean = sum / n;
        sd[k] = std::sqrt(std::max(0.0, sum2 / n - mean * mean));
        rays[k] = counters.total();
        // Within 4 standard errors of the closed form (and 2%).
        EXPECT_NEAR(mean, 20.0, std::min(0.4, 4.0 * sd[k] / std::sqrt(double(n)) + 0.05)) << "threshold " << thresholds[k];
    }
    std::printf("a = 0.95, per-path standard deviation: %.2f at threshold 1, %.2f at 0.1 (rays %.2fx)\n", sd[0], sd[1],
                double(rays[1]) / double(rays[0]));
    EXPECT_LT(sd[1], 0.3 * sd[0]);
}

// The cut is never at a vertex with a sharp lobe (metal or glass below roughness 0.5): there the path goes
// on, up to 4 more bounces. In a furnace of smooth metal every vertex is sharp, so every tail comes after
// exactly bounces + 4 extension rays; in a Lambertian one after exactly `bounces`.
TEST(Furnace, ScatteredRadianceBouncesThroughSharpLobes) {
    ThreadScope threads(1);
    for (bool metal : {false, true}) {
        Material m = diffuseEmitter(0.8f, glm::vec3(1.0f));
        if (metal) {
            m.metallic = 1.0f;
            m.roughness = 0.3f;
        }
        Scene scene = test::makeSphereFurnace(m);
        Accel accel(scene);
        LightSampler lights(scene);
        PathTracer tracer(scene, accel, lights);
        for (int bounces : {1, 2}) {
            uint64_t tails = 0;
            const ScatteredRadiance tail = [&](const SurfaceInteraction&) {
                ++tails;
                return glm::vec3(1.0f);
            };
            RayCounters counters;
            const int n = 2000;
            for (int i = 0; i < n; ++i) {
                Sampler sampler(0xc0ffeeu, uint32_t(i));
                const glm::vec2 u = sampler.get2D();
                const float z = 1.0f - 2.0f * u.x, r = std::sqrt(std::max(0.0f, 1.0f - z * z)), phi = 6.2831853f * u.y;
                Hit hit = accel.intersect(glm::vec3(0.0f), glm::vec3(r * std::cos(phi), r * std::sin(phi), z));
                ASSERT_TRUE(hit.valid());
                const uint64_t before = counters.extension, tailsBefore = tails;
                tracer.scatteredRadiance(makeInteraction(scene, hit, glm::vec3(r * std::cos(phi), r * std::sin(phi), z)), sampler, bounces,
                                         tail, counters);
                if (tails > tailsBefore) {
                    EXPECT_EQ(counters.extension - before, uint64_t(bounces + (metal ? 4 : 0))) << i;
                }
            }
            EXPECT_GT(tails, uint64_t(n / 2)) << (metal ? "metal" : "diffuse") << ", " << bounces << " bounce(s)";
        }
    }
}

TEST(Furnace, GlossyEnclosureConservesEnergy) {
    // A white rough metal enclosure (alpha 1): the single-scattering lobe loses energy, so the unbounded
    // radiance lies between the one-bounce value 1 + E(n) = 2 - ln 2 and the geometric series with the
    // largest directional albedo, 1 / (1 - max E).
    Material m;
    m.baseColor = glm::vec3(1.0f);
    m.metallic = 1.0f;
    m.roughness = 1.0f;
    m.emission = glm::vec3(1.0f);
    Scene scene = test::makeSphereFurnace(m);
    BsdfParams p;
    p.metallic = 1.0f;
    p.roughness = 1.0f;
    Bsdf bsdf(Frame::fromNormal({0, 0, 1}), p);
    double maxE = 0.0;
    for (double theta = 0.0; theta < 1.57; theta += 0.05) {
        glm::vec3 wo(float(std::sin(theta)), 0.0f, float(std::cos(theta)));
        double e = 0.0;
        const int n = 256;
        for (int i = 0; i < n; ++i) {
            double ct = (i + 0.5) / n, st = std::sqrt(1 - ct * ct);
            for (int j = 0; j < 2 * n; ++j) {
                double phi = 2 * kPi * (j + 0.5) / (2 * n);
                e += bsdf.eval(wo, glm::vec3(float(st * std::cos(phi)), float(st * std::sin(phi)), float(ct))).x * ct;
            }
        }
        maxE = std::max(maxE, e * (1.0 / n) * (2 * kPi / (2 * n)));
    }
    EXPECT_LE(maxE, 1.0);
    Image image = renderScene(scene, 2, 1 << 15, 0);
    double L = image.mean().x;
    EXPECT_GT(L, 2.0 - std::log(2.0));
    EXPECT_LT(L, 1.0 / (1.0 - maxE));
}

TEST(PunctualLights, DirectionalLightOnALambertianPlane) {
    // L = (a / pi) E cos(theta) for a directional light of irradiance E at 60 degrees from the normal.
    float a = 0.6f;
    Scene scene = test::makeLitPlane(a);
    PunctualLight sun;
    sun.type = PunctualLight::Type::Directional;
    sun.intensity = glm::vec3(2.0f, 4.0f, 8.0f);
    sun.direction = glm::normalize(glm::vec3(std::sin(kPi / 3), 0.0, -std::cos(kPi / 3)));
    scene.lights.push_back(sun);
    Image image = renderScene(scene, 8, 4, 0);
    glm::vec3 expected = (a / float(kPi)) * sun.intensity * 0.5f;
    expectUniform(image, expected, 1e-4, 1e-4);
}

TEST(PunctualLights, PointAndSpotLightInverseSquareAndCone) {
    // A point light of intensity I at height h: directly below it, L = (a / pi) I / h^2. A spot light pointing
    // straight down gives the same inside its inner cone.
    float a = 0.5f, h = 2.0f;
    for (PunctualLight::Type type : {PunctualLight::Type::Point, PunctualLight::Type::Spot}) {
        Scene scene = test::makeLitPlane(a);
        scene.cameras[0].xmag = scene.cameras[0].ymag = 0.01f;  // a tiny patch under the light
        PunctualLight l;
        l.type = type;
        l.position = glm::vec3(0, 0, h);
        l.direction = glm::vec3(0, 0, -1);
        l.intensity = glm::vec3(10.0f);
        l.cosInnerCone = std::cos(0.3f);
        l.cosOuterCone = std::cos(0.5f);
        scene.lights.push_back(l);
        scene.updateBounds();
        Image image = renderScene(scene, 4, 4, 0);
        float expected = a / float(kPi) * 10.0f / (h * h);
        EXPECT_NEAR(image.mean().x, expected, 1e-3 * expected);
    }
}

}  // namespace
}  // namespace nrad
