// Path tracer on real scenes: byte-identical images for 1 and 2 threads, every external scene renders
// with finite pixels, and the bundled Cornell box's directly visible light has its stated radiance.
#include <cmath>
#include <cstring>
#include <limits>
#include <random>
#include <vector>

#include <gtest/gtest.h>

#include "baker/render/accel.h"
#include "baker/render/camera.h"
#include "baker/lights/light_sampler.h"
#include "baker/lights/light_selection.h"
#include "baker/render/path_tracer.h"
#include "baker/scene/environment.h"
#include "baker/scene/gltf_loader.h"
#include "baker/util/threads.h"
#include "support/test_paths.h"

namespace nrad {
namespace {

Image render(const Scene& scene, const RenderSettings& s, RenderStats* stats = nullptr) {
    Accel accel(scene);
    LightSampler lights(scene);
    PathTracer tracer(scene, accel, lights);
    Camera camera = scene.cameras.empty() ? frameBounds(scene.bounds) : scene.cameras[0];
    return tracer.render(camera, s, stats);
}

// Accel returns each hit's geometric normal and ray margin from a table built once; they must be the bits
// TriangleMesh::geometricNormal and triangleMargin give for the triangle hit (makeInteraction, viewable and
// the spawn distances use them in their place), on a real level of 58,772 triangles from random rays.
TEST(Accel, HitsCarryTheirTrianglesNormalAndMarginBitForBit) {
    Scene scene = loadGltf(test::externalScene("Sauerbraten_zdm2/zdm2.glb"));
    Accel accel(scene);
    std::mt19937 rng(3);
    std::uniform_real_distribution<float> u(0.0f, 1.0f);
    size_t hits = 0;
    for (int i = 0; i < 20000; ++i) {
        const glm::vec3 o = scene.bounds.lower + glm::vec3(u(rng), u(rng), u(rng)) * (scene.bounds.upper - scene.bounds.lower);
        const float z = 2.0f * u(rng) - 1.0f, a = 6.2831853f * u(rng), r = std::sqrt(1.0f - z * z);
        const Hit hit = accel.intersect(o, glm::vec3(r * std::cos(a), r * std::sin(a), z));
        if (!hit.valid()) continue;
        ++hits;
        const glm::vec3 ng = scene.mesh.geometricNormal(hit.triangle);
        ASSERT_EQ(std::memcmp(&hit.ng, &ng, sizeof ng), 0) << "triangle " << hit.triangle;
        const float margin = triangleMargin(scene.mesh, hit.triangle);
        ASSERT_EQ(std::memcmp(&hit.margin, &margin, sizeof margin), 0) << "triangle " << hit.triangle;
        ASSERT_GT(hit.margin, 0.0f);
    }
    EXPECT_GT(hits, 10000u);  // a closed level: most rays from inside its box hit something
}

// The batched queries go through Embree's ray streams, whose kernels are not the single-ray ones: they must
// give the same triangles and the same bits of t, u and v (the batched tracer's images depend on it), on a real
// level from random rays, and, on a scene with alpha-blended materials (the coverage filter), the same
// occlusion.
TEST(Accel, StreamsGiveTheSingleRayResultsBitForBit) {
    for (const char* path : {"Sauerbraten_zdm2/zdm2.glb", "LightsPunctualLamp/glTF/LightsPunctualLamp.gltf"}) {
        Scene scene = loadGltf(test::externalScene(path));
        Accel accel(scene);
        std::mt19937 rng(5);
        std::uniform_real_distribution<float> u(0.0f, 1.0f);
        std::vector<RayQuery> rays(5000);
        for (RayQuery& q : rays) {
            q.origin = scene.bounds.lower + glm::vec3(u(rng), u(rng), u(rng)) * (scene.bounds.upper - scene.bounds.lower);
            const float z = 2.0f * u(rng) - 1.0f, a = 6.2831853f * u(rng), r = std::sqrt(1.0f - z * z);
            q.direction = glm::vec3(r * std::cos(a), r * std::sin(a), z);
            q.tnear = u(rng) < 0.5f ? 0.0f : 1e-3f;
            q.tfar = u(rng) < 0.5f ? std::numeric_limits<float>::infinity() : 0.5f * glm::length(scene.bounds.upper - scene.bounds.lower) * u(rng);
        }
        std::vector<Hit> hits(rays.size());
        std::vector<uint8_t> blocked(rays.size());
        accel.intersect(rays.data(), rays.size(), hits.data());
        accel.occluded(rays.data(), rays.size(), blocked.data());
        size_t hitCount = 0, blockedCount = 0;
        for (size_t i = 0; i < rays.size(); ++i) {
            const RayQuery& q = rays[i];
            const Hit one = accel.intersect(q.origin, q.direction, q.tnear, q.tfar);
            ASSERT_EQ(hits[i].triangle, one.triangle) << path << ", ray " << i;
            ASSERT_EQ(std::memcmp(&hits[i], &one, sizeof one), 0) << path << ", ray " << i;
            ASSERT_EQ(blocked[i] != 0, accel.occluded(q.origin, q.direction, q.tnear, q.tfar)) << path << ", ray " << i;
            hitCount += one.valid();
            blockedCount += blocked[i];
        }
        EXPECT_GT(hitCount, 250u) << path;  // the lamp fills a small part of its box
        EXPECT_GT(blockedCount, 250u) << path;
    }
}

// The batched tracer (one vertex of many paths at a time, rays in streams) against the one-path tracer it
// reorganises: the same image bit for bit (camera rays in incoherent streams), for batches of 256, an odd size
// and more than a tile's pixels, on scenes
// that exercise area lights and glossy metal, punctual lights with alpha blending, textures, a sky seen
// through a level's openings (escaped paths) and a light selector (the per-path selection buffers).
// A batch's camera rays (generated in vectorised loops) are the one-ray generate()'s, bit for bit: a turned
// perspective camera and an orthographic one, random raster points, the image's corners and chunks' edges.
TEST(CameraRays, BatchIsTheOneRayCallBitForBit) {
    std::mt19937 rng(3);
    Camera camera;
    camera.position = glm::vec3(0.3f, -2.0f, 7.5f);
    const glm::vec3 right = glm::normalize(glm::vec3(0.9f, 0.1f, -0.3f));
    const glm::vec3 up = glm::normalize(glm::cross(glm::vec3(0.2f, 0.1f, 1.0f), right));
    camera.worldFromCamera = glm::mat3(right, up, glm::cross(right, up));
    camera.yfov = 0.9f;
    camera.ymag = 2.5f;
    for (Camera::Type type : {Camera::Type::Perspective, Camera::Type::Orthographic}) {
        camera.type = type;
        const CameraRays rays(camera, 97, 61);
        std::uniform_real_distribution<float> ux(0.0f, 97.0f), uy(0.0f, 61.0f);
        std::vector<float> x, y;
        for (float cx : {0.0f, 97.0f})
            for (float cy : {0.0f, 61.0f}) x.push_back(cx), y.push_back(cy);
        while (x.size() < 203) x.push_back(ux(rng)), y.push_back(uy(rng));
        std::vector<RayQuery> batch(x.size());
        rays.generate(x.data(), y.data(), x.size(), batch.data());
        for (size_t k = 0; k < x.size(); ++k) {
            glm::vec3 o, d;
            rays.generate(x[k], y[k], o, d);
            ASSERT_EQ(std::memcmp(&o, &batch[k].origin, sizeof o), 0) << k;
            ASSERT_EQ(std::memcmp(&d, &batch[k].direction, sizeof d), 0) << k;
        }
    }
}

TEST(PathTracer, BatchedImageIsTheOnePathImageBitForBit) {
    struct Case {
        const char* scene;
        bool external;
        bool sky;
        NeeMode nee;
    };
    for (const Case& c : {Case{"scenes/cornell-box-glossy/cornell-box-glossy.gltf", false, false, NeeMode::Power},
                          Case{"scenes/cornell-box/cornell-box.gltf", false, false, NeeMode::Uniform},
                          Case{"LightsPunctualLamp/glTF/LightsPunctualLamp.gltf", true, false, NeeMode::Power},
                          Case{"AvocadoDraco/glTF-Draco/Avocado.gltf", true, true, NeeMode::Power},
                          Case{"Sauerbraten_zdm2/zdm2.glb", true, true, NeeMode::Uniform}}) {
        Scene scene = loadGltf(c.external ? test::externalScene(c.scene) : test::sourcePath(c.scene));
        if (c.sky) scene.environment = parseEnvironment("0.5,1,2");
        Accel accel(scene);
        LightSampler lights(scene);
        NeeSettings nee;
        nee.mode = c.nee;
        LightSelector selector(lights, scene.bounds, nee);
        PathTracer tracer(scene, accel, lights, &selector);
        Camera camera = scene.cameras.empty() ? frameBounds(scene.bounds) : scene.cameras[0];
        RenderSettings s;
        s.width = 36;
        s.height = 20;
        s.spp = 4;
        s.tileSize = 16;
        s.batchSize = 1;
        s.coherentCameraRays = false;
        RenderStats oneStats;
        const Image one = tracer.render(camera, s, &oneStats);
        EXPECT_GT(one.mean().x + one.mean().y + one.mean().z, 0.0) << c.scene;
        for (int batch : {256, 7, 1000}) {
            s.batchSize = batch;
            RenderStats stats;
            const Image batched = tracer.render(camera, s, &stats);
            ASSERT_EQ(batched.pixels.size(), one.pixels.size());
            EXPECT_EQ(std::memcmp(batched.pixels.data(), one.pixels.data(), one.pixels.size() * sizeof(glm::vec3)), 0)
                << c.scene << ", batches of " << batch;
            EXPECT_EQ(stats.rays.primary, oneStats.rays.primary);
            EXPECT_EQ(stats.rays.extension, oneStats.rays.extension) << c.scene;
            EXPECT_EQ(stats.rays.shadow, oneStats.rays.shadow) << c.scene;
        }
        // Camera rays in coherent streams (the default): Embree's packet kernels, whose hits differ in the last
        // bits now and then: nearly every pixel the same, none far off.
        s.batchSize = 256;
        s.coherentCameraRays = true;
        const Image coherent = tracer.render(camera, s);
        size_t same = 0;
        double diff = 0.0, sum = 0.0;
        for (size_t i = 0; i < one.pixels.size(); ++i) {
            same += std::memcmp(&coherent.pixels[i], &one.pixels[i], sizeof(glm::vec3)) == 0;
            diff += std::abs(double(coherent.pixels[i].y) - double(one.pixels[i].y));
            sum += double(one.pixels[i].y);
        }
        EXPECT_GE(double(same), 0.99 * double(one.pixels.size())) << c.scene;
        EXPECT_LE(diff, 0.01 * sum) << c.scene;
    }
}

// Training estimates (PathTracer::estimate, in batches: the bakes' targets) against the one-path calls bit for
// bit, as the baker's tracer has them: engine-drawn lights excluded (mixed lighting), the training roulette
// threshold, Monte Carlo paths and integral targets cut after two bounces with a tail. The glossy box's quad
// light goes through the scatter lanes, the engine-drawn point light (left out at the first vertex, added at the
// cut) through the scalar path.
TEST(PathTracer, BatchedEstimatesAreTheOnePathCallsBitForBit) {
    Scene scene = loadGltf(test::sourcePath("scenes/cornell-box-glossy/cornell-box-glossy.gltf"));
    PunctualLight bulb;
    bulb.type = PunctualLight::Type::Point;
    bulb.position = scene.bounds.center() + glm::vec3(0.1f, -0.2f, 0.15f) * (scene.bounds.upper - scene.bounds.lower);
    bulb.intensity = glm::vec3(0.4f, 0.3f, 0.2f);
    bulb.runtimeDirect = true;
    scene.lights.push_back(bulb);
    Accel accel(scene);
    LightSampler lights(scene);
    PathTracer tracer(scene, accel, lights);
    tracer.setExcludeEngineDrawnDirect(true);
    tracer.setRouletteThreshold(0.1f);
    // Start points: where rays from the camera through a grid hit.
    const Camera camera = scene.cameras.empty() ? frameBounds(scene.bounds) : scene.cameras[0];
    CameraRays rays(camera, 12, 12);
    std::vector<SurfaceInteraction> points;
    for (int y = 0; y < 12; ++y)
        for (int x = 0; x < 12; ++x) {
            glm::vec3 o, d;
            rays.generate(float(x) + 0.5f, float(y) + 0.5f, o, d);
            const Hit hit = accel.intersect(o, d);
            if (hit.valid()) points.push_back(makeInteraction(scene, hit, d));
        }
    ASSERT_GT(points.size(), 100u);
    std::vector<PathStart> starts;
    for (size_t k = 0; k < points.size(); ++k)
        for (uint32_t j = 0; j < 5; ++j) starts.push_back({&points[k], hashU32(uint32_t(k) + 17u), j});
    const ScatteredRadiance tail = [](const SurfaceInteraction& si) {
        return glm::vec3(0.2f, 0.1f, 0.05f) * (1.5f + si.ns.y) + 0.01f * si.p;
    };
    for (bool integral : {false, true}) {
        std::vector<glm::vec3> batched(starts.size());
        RayCounters batchedRays, oneRays;
        tracer.estimate(starts.data(), starts.size(), 0, integral ? &tail : nullptr, 2, batchedRays, batched.data());
        double sum = 0.0;
        for (size_t i = 0; i < starts.size(); ++i) {
            Sampler sampler(starts[i].stream, starts[i].index);
            const glm::vec3 one = integral ? tracer.scatteredRadiance(*starts[i].si, sampler, 2, tail, oneRays)
                                           : tracer.outgoingRadiance(*starts[i].si, sampler, 0, oneRays);
            ASSERT_EQ(std::memcmp(&batched[i], &one, sizeof(glm::vec3)), 0)
                << (integral ? "integral" : "Monte Carlo") << ", path " << i;
            sum += double(one.x + one.y + one.z);
        }
        EXPECT_GT(sum, 0.0);
        EXPECT_EQ(batchedRays.extension, oneRays.extension);
        EXPECT_EQ(batchedRays.shadow, oneRays.shadow);
    }
}

TEST(PathTracer, ImageIsByteIdenticalForOneAndTwoThreads) {
    Scene scene = loadGltf(test::sourcePath("scenes/cornell-box-glossy/cornell-box-glossy.gltf"));
    RenderSettings s;
    s.width = s.height = 40;
    s.spp = 8;
    s.seed = 42;
    s.tileSize = 8;
    Image one, two;
    {
        ThreadScope threads(1);
        one = render(scene, s);
    }
    {
        ThreadScope threads(2);
        two = render(scene, s);
    }
    ASSERT_EQ(one.pixels.size(), two.pixels.size());
    EXPECT_EQ(std::memcmp(one.pixels.data(), two.pixels.data(), one.pixels.size() * sizeof(glm::vec3)), 0);
    // A different seed gives a different image (the seed is really used).
    s.seed = 43;
    Image other = render(scene, s);
    EXPECT_NE(std::memcmp(one.pixels.data(), other.pixels.data(), one.pixels.size() * sizeof(glm::vec3)), 0);
}

TEST(PathTracer, PathLengthOneSeesOnlyTheLight) {
    Scene scene = loadGltf(test::sourcePath("scenes/cornell-box/cornell-box.gltf"));
    RenderSettings s;
    s.width = s.height = 64;
    s.spp = 1;
    s.maxDepth = 1;
    Image image = render(scene, s);
    int lit = 0;
    for (const glm::vec3& p : image.pixels) {
        if (p.x > 0.0f) {
            ++lit;
            // The light's radiance is (17, 12, 4); a pixel sees it entirely or not at all at 1 spp.
            EXPECT_FLOAT_EQ(p.x, 17.0f);
            EXPECT_FLOAT_EQ(p.y, 12.0f);
            EXPECT_FLOAT_EQ(p.z, 4.0f);
        }
    }
    // The 130 x 105 mm light seen from the classic camera covers about 0.8% of the image.
    EXPECT_GT(lit, 10);
    EXPECT_LT(lit, 80);
}

struct ExternalRender {
    const char* path;
    bool lit;  // has emissive surfaces or punctual lights
};

class ExternalRenderTest : public ::testing::TestWithParam<ExternalRender> {};

TEST_P(ExternalRenderTest, RendersWithFinitePixels) {
    Scene scene = loadGltf(test::externalScene(GetParam().path));
    RenderSettings s;
    s.width = s.height = 32;
    s.spp = 2;
    RenderStats stats;
    Image image = render(scene, s, &stats);
    for (const glm::vec3& p : image.pixels)
        for (int k = 0; k < 3; ++k) ASSERT_TRUE(std::isfinite(p[k]) && p[k] >= 0.0f);
    EXPECT_EQ(stats.rays.nonFiniteSamples, 0u);
    EXPECT_EQ(stats.rays.primary, 32u * 32u * 2u);
    if (GetParam().lit)
        EXPECT_GT(image.mean().x + image.mean().y + image.mean().z, 0.0);
    else
        EXPECT_EQ(image.mean().x, 0.0);  // no light sources, nothing to see
}

INSTANTIATE_TEST_SUITE_P(SharedScenes, ExternalRenderTest,
                         ::testing::Values(ExternalRender{"CornellBox/CornellBox.glb", true},
                                           ExternalRender{"BoxDraco/glTF-Draco/Box.gltf", false},
                                           ExternalRender{"AvocadoDraco/glTF-Draco/Avocado.gltf", false},
                                           ExternalRender{"LightsPunctualLamp/glTF/LightsPunctualLamp.gltf", true},
                                           ExternalRender{"EmissiveStrengthTest/glTF/EmissiveStrengthTest.gltf", true},
                                           ExternalRender{"MetalRoughSpheresNoTextures/glTF/MetalRoughSpheresNoTextures.gltf", false},
                                           ExternalRender{"Sauerbraten_zdm2/zdm2.glb", false}),
                         [](const ::testing::TestParamInfo<ExternalRender>& param) {
                             std::string name(param.param.path);
                             name = name.substr(0, name.find('/'));
                             return name;
                         });

}  // namespace
}  // namespace nrad
