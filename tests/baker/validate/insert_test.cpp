// Objects placed after the bake (issue 42): insertion into a scene, the irradiance-probe baseline's closed forms,
// and an inserted sphere rendered through the asset's volume query against the closed form.
#include <cmath>
#include <cstdio>

#include <gtest/gtest.h>
#include <nrad/format.h>
#include <nrad/nrad.hpp>

#include "baker/bake/baker.h"
#include "baker/nn/random.h"
#include "baker/render/accel.h"
#include "baker/render/neural_render.h"
#include "baker/render/path_tracer.h"
#include "baker/scene/gltf_loader.h"
#include "baker/util/maths.h"
#include "baker/validate/sh_irradiance.h"
#include "support/test_paths.h"
#include "support/test_scenes.h"

namespace nrad {
namespace {

std::string sphereFile() { return test::sourcePath("scenes/objects/sphere.gltf"); }

TEST(InsertObject, AppendsTheObjectsTrianglesAndMaterialsMovedAndRecordsThem) {
    Scene scene = test::makeScaffold();
    const Scene sphere = loadGltf(sphereFile());
    ASSERT_GT(sphere.mesh.triangleCount(), 1000u);
    const size_t before = scene.mesh.triangleCount();
    insertObject(scene, sphere, glm::vec3(0.3f, -0.2f, 0.1f), "sphere@0.3,-0.2,0.1");
    insertObject(scene, sphere, glm::vec3(-0.5f, 0.0f, 0.0f), "sphere@-0.5,0,0");
    ASSERT_EQ(scene.mesh.triangleCount(), before + 2 * sphere.mesh.triangleCount());
    ASSERT_EQ(scene.insertedObjects.size(), 2u);
    EXPECT_EQ(scene.insertedObjects[0], before);
    EXPECT_EQ(scene.insertedObject(before - 1), -1);
    EXPECT_EQ(scene.insertedObject(before), 0);
    EXPECT_EQ(scene.insertedObject(before + sphere.mesh.triangleCount()), 1);
    EXPECT_EQ(scene.insertedObject(scene.mesh.triangleCount() - 1), 1);
    EXPECT_EQ(scene.insertedNames[1], "sphere@-0.5,0,0");
    ASSERT_EQ(scene.materials.size(), 3u);
    EXPECT_EQ(scene.mesh.materialIds[before], 1u);
    EXPECT_EQ(scene.mesh.materialIds.back(), 2u);
    EXPECT_FLOAT_EQ(scene.materials[1].baseColor.x, 0.8f);
    // The first copy's vertices moved by its offset: its centre at 0.3, -0.2, 0.1 (radius 0.08).
    Bounds3 first;
    for (size_t t = before; t < before + sphere.mesh.triangleCount(); ++t)
        for (int k = 0; k < 3; ++k) first.extend(scene.mesh.positions[scene.mesh.triangles[t][k]]);
    EXPECT_NEAR(first.center().x, 0.3f, 1e-5f);
    EXPECT_NEAR(first.center().y, -0.2f, 1e-5f);
    EXPECT_NEAR(first.extent().x, 0.16f, 1e-5f);
    EXPECT_THROW(insertObject(scene, Scene(), glm::vec3(0.0f), "empty"), SceneError);
}

TEST(ShIrradianceProbes, AUniformSkyGivesItsRadianceAtEveryNormal) {
    Scene scene = test::makeScaffold();
    scene.environment.kind = Environment::Kind::Constant;
    const glm::vec3 L(0.5f, 1.0f, 2.0f);
    scene.environment.color = L;
    Accel accel(scene);
    LightSampler lights(scene);
    PathTracer tracer(scene, accel, lights);
    ShIrradianceFit fit;
    fit.normalsPerProbe = 128;
    fit.pathsPerNormal = 32;
    ShIrradianceStats stats;
    const ShIrradianceGrid g = fitShIrradianceGrid(tracer, glm::vec3(-0.8f), glm::vec3(0.8f), glm::uvec3(2, 3, 2), fit, &stats);
    EXPECT_EQ(stats.probes, 12u);
    EXPECT_EQ(stats.leftOut, 0u);
    EXPECT_EQ(g.bytes(), 12u * 54u + 2u);
    SplitMix64 r(7);
    double worst = 0.0;
    for (int i = 0; i < 200; ++i) {
        const glm::vec3 p(1.6f * r.uniform() - 0.8f, 1.6f * r.uniform() - 0.8f, 1.6f * r.uniform() - 0.8f);
        const float z = 1.0f - 2.0f * r.uniform(), phi = 2.0f * kPi * r.uniform(), s = std::sqrt(1.0f - z * z);
        const glm::vec3 D = g.evaluate(p, {s * std::cos(phi), s * std::sin(phi), z});
        for (int c = 0; c < 3; ++c) worst = std::max(worst, double(std::fabs(D[c] / L[c] - 1.0f)));
    }
    std::printf("uniform sky: worst relative error %.2e\n", worst);
    EXPECT_LT(worst, 0.03);  // E = pi L is in L2 exactly: what is left is the paths' noise (and fp16)
    // The budget: grown a probe at a time along the widest spacing while the bytes allow (x, then y; z would not fit).
    EXPECT_EQ(irradianceDimsForBudget(glm::vec3(0.0f), glm::vec3(2.0f, 1.0f, 1.0f), 6 * 54 + 1), glm::uvec3(3, 2, 1));
    EXPECT_EQ(irradianceDimsForBudget(glm::vec3(0.0f), glm::vec3(2.0f, 1.0f, 1.0f), 6 * 54), glm::uvec3(3, 1, 1));
}

TEST(ShIrradianceProbes, AProbeInsideAClosedSolidIsLeftOut) {
    Scene scene = loadGltf(sphereFile());  // closed, single-sided, facing out
    scene.environment.kind = Environment::Kind::Constant;
    scene.environment.color = glm::vec3(1.0f);
    Accel accel(scene);
    LightSampler lights(scene);
    PathTracer tracer(scene, accel, lights);
    ShIrradianceStats stats;
    const ShIrradianceGrid g = fitShIrradianceGrid(tracer, glm::vec3(-0.01f), glm::vec3(0.01f), glm::uvec3(1), ShIrradianceFit{}, &stats);
    EXPECT_EQ(stats.leftOut, 1u);
    EXPECT_EQ(g.valid[0], 0);
    EXPECT_EQ(g.evaluate(glm::vec3(0.0f), glm::vec3(0, 1, 0)), glm::vec3(0.0f));
}

// An unoccluded white sphere (albedo 0.8, Lambertian) under a uniform sky of radiance L, placed after the bake:
// through the asset's volume query every pixel of it reads 0.8 L, as the path tracer says.
TEST(InsertedObjects, AWhiteSphereUnderAUniformSkyIsShadedThroughTheVolumeQuery) {
    Scene scene = test::makeScaffold();
    scene.environment.kind = Environment::Kind::Constant;
    const glm::vec3 L(0.5f, 1.0f, 2.0f);
    scene.environment.color = L;
    BakeSettings s;
    s.grid = {2, 2, 2};
    s.samples.points = 4000;
    s.samples.paths = 4;
    s.train.epochs = 300;
    s.volume.enabled = true;
    s.volume.pointsPerCell = 1500;
    s.volume.paths = 8;
    const BakeResult baked = bakeScene(scene, s);
    const std::vector<uint8_t> bytes = format::encode(baked.asset);
    nrad::Asset asset;
    ASSERT_EQ(asset.loadFromMemory(bytes.data(), bytes.size()), NRAD_OK);

    insertObject(scene, loadGltf(sphereFile()), glm::vec3(0.1f, 0.05f, -0.1f), "sphere");
    Accel accel(scene);
    Camera camera;
    camera.position = glm::vec3(0.1f, 0.05f, 0.4f);  // 0.5 m in front of the sphere, looking down -z at it
    camera.yfov = 0.4f;
    RenderSettings rs;
    rs.width = rs.height = 48;
    rs.spp = 1;
    Image image;
    NeuralRenderStats stats;
    ASSERT_EQ(renderThroughAsset(scene, accel, asset.get(), camera, rs, image, &stats), NRAD_OK);
    EXPECT_GT(stats.volumeEvaluations, 400u);
    // The pixels that see the sphere (not the sky, which reads L exactly): 0.8 L.
    double worst = 0.0;
    size_t seen = 0;
    for (const glm::vec3& px : image.pixels) {
        if (std::fabs(px.z / L.z - 1.0f) < 1e-4f) continue;  // the sky
        ++seen;
        for (int c = 0; c < 3; ++c) worst = std::max(worst, double(std::fabs(px[c] / (0.8f * L[c]) - 1.0f)));
    }
    std::printf("white sphere: %zu pixels, worst relative error %.4f\n", seen, worst);
    EXPECT_EQ(seen, stats.volumeEvaluations);
    EXPECT_LT(worst, 0.05);
}

}  // namespace
}  // namespace nrad
