// glTF import: the external scenes load with the triangle counts of their SOURCES.md (Draco included),
// materials, emission and punctual lights come through with the right values, edge cases are handled.
#include "baker/scene/gltf_loader.h"

#include <algorithm>
#include <cmath>

#include <gtest/gtest.h>

#include "support/test_paths.h"

namespace nrad {
namespace {

using test::externalScene;
using test::sourcePath;

struct ExternalScene {
    const char* path;
    size_t triangles;  // "Scene tris" of SOURCES.md
    size_t dracoPrimitives;
};

class ExternalSceneTest : public ::testing::TestWithParam<ExternalScene> {};

TEST_P(ExternalSceneTest, LoadsWithTheExpectedTriangleCount) {
    const ExternalScene& e = GetParam();
    Scene scene = loadGltf(externalScene(e.path));
    EXPECT_EQ(scene.stats.trianglesRead, e.triangles);
    EXPECT_EQ(scene.mesh.triangleCount() + scene.stats.degenerateTrianglesDropped, e.triangles);
    EXPECT_EQ(scene.stats.dracoPrimitives, e.dracoPrimitives);
    EXPECT_FALSE(scene.bounds.empty());
    ASSERT_EQ(scene.mesh.normals.size(), scene.mesh.positions.size());
    for (const glm::vec3& n : scene.mesh.normals) {
        float len = glm::length(n);
        ASSERT_TRUE(std::abs(len - 1.0f) < 1e-3f || len == 0.0f) << len;
    }
    for (uint32_t m : scene.mesh.materialIds) ASSERT_LT(m, scene.materials.size());
}

INSTANTIATE_TEST_SUITE_P(
    SharedScenes, ExternalSceneTest,
    ::testing::Values(ExternalScene{"CornellBox/CornellBox.glb", 36, 0},
                      ExternalScene{"BoxDraco/glTF-Draco/Box.gltf", 12, 1},
                      ExternalScene{"AvocadoDraco/glTF-Draco/Avocado.gltf", 682, 1},
                      ExternalScene{"LightsPunctualLamp/glTF/LightsPunctualLamp.gltf", 6000, 0},
                      ExternalScene{"EmissiveStrengthTest/glTF/EmissiveStrengthTest.gltf", 90, 0},
                      ExternalScene{"MetalRoughSpheresNoTextures/glTF/MetalRoughSpheresNoTextures.gltf", 1040409, 0},
                      ExternalScene{"Sauerbraten_zdm2/zdm2.glb", 58772, 0}),
                         [](const ::testing::TestParamInfo<ExternalScene>& param) {
                             std::string name(param.param.path);
                             name = name.substr(0, name.find('/'));
                             return name;
                         });

TEST(GltfLoader, CornellBoxEmitterHasEmissiveStrength) {
    Scene scene = loadGltf(externalScene("CornellBox/CornellBox.glb"));
    ASSERT_EQ(scene.materials.size(), 5u);
    const Material& light = scene.materials[0];
    EXPECT_EQ(light.name, "Emitter_Light_temp");
    EXPECT_FLOAT_EQ(light.emission.x, 100.0f);
    EXPECT_FLOAT_EQ(light.emission.z, 100.0f);
    EXPECT_TRUE(light.doubleSided);
    EXPECT_FLOAT_EQ(scene.materials[3].baseColor.x, 0.5f);  // red
    EXPECT_FLOAT_EQ(scene.materials[3].baseColor.y, 0.0f);
    // Bounds from SOURCES.md: x in [-556, 0], y in [0, 548.8], z in [-559.2, 0].
    EXPECT_NEAR(scene.bounds.lower.x, -556.0f, 0.5f);
    EXPECT_NEAR(scene.bounds.upper.y, 548.8f, 0.5f);
    EXPECT_NEAR(scene.bounds.lower.z, -559.2f, 0.5f);
    EXPECT_GT(scene.emissiveTriangleCount(), 0u);
    EXPECT_TRUE(scene.cameras.empty());
}

TEST(GltfLoader, EmissiveStrengthScalesTheEmissiveFactor) {
    Scene scene = loadGltf(externalScene("EmissiveStrengthTest/glTF/EmissiveStrengthTest.gltf"));
    std::vector<float> strengths;
    for (const Material& m : scene.materials)
        if (m.emissive()) {
            float s = m.emission.x / 0.1f;
            EXPECT_NEAR(m.emission.y, 0.5f * s, 1e-4f * s);
            EXPECT_NEAR(m.emission.z, 0.9f * s, 1e-4f * s);
            strengths.push_back(std::round(s));
        }
    std::sort(strengths.begin(), strengths.end());
    EXPECT_EQ(strengths, (std::vector<float>{1, 2, 4, 8, 16}));
}

TEST(GltfLoader, PunctualLightsAreConvertedFromCandela) {
    Scene scene = loadGltf(externalScene("LightsPunctualLamp/glTF/LightsPunctualLamp.gltf"));
    ASSERT_EQ(scene.lights.size(), 5u);
    // Name -> (candela, colour) from the file; radiant intensity = colour x candela / 683 lm/W.
    struct Expected {
        const char* name;
        float candela;
        glm::vec3 color;
    };
    const Expected expected[] = {{"Point", 15.0f, {1.0f, 0.631875f, 0.2390998f}},
                                 {"Point.002", 1.5f, {1.0f, 1.0f, 1.0f}},
                                 {"Point.003", 80.0f, {0.2122308f, 0.5906190f, 0.5583405f}},
                                 {"Point.001", 80.0f, {0.2122308f, 0.5906190f, 0.5583405f}},
                                 {"Point.004", 180.0f, {1.0f, 0.6278365f, 0.5012404f}}};
    for (const Expected& e : expected) {
        auto it = std::find_if(scene.lights.begin(), scene.lights.end(), [&](const PunctualLight& l) { return l.name == e.name; });
        ASSERT_NE(it, scene.lights.end()) << e.name;
        EXPECT_EQ(it->type, PunctualLight::Type::Point);
        for (int k = 0; k < 3; ++k) EXPECT_NEAR(it->intensity[k], e.color[k] * e.candela / 683.0f, 1e-6f) << e.name;
    }
}

TEST(GltfLoader, TexturesAreDecodedAndSrgbLinearised) {
    Scene scene = loadGltf(externalScene("AvocadoDraco/glTF-Draco/Avocado.gltf"));
    ASSERT_EQ(scene.materials.size(), 1u);
    const Material& m = scene.materials[0];
    ASSERT_TRUE(m.baseColorTexture.valid());
    ASSERT_TRUE(m.metallicRoughnessTexture.valid());
    const Texture& base = scene.textures[size_t(m.baseColorTexture.texture)];
    EXPECT_GT(base.width, 0);
    EXPECT_GT(base.height, 0);
    // An sRGB-decoded average is darker than the encoded one; all texels in [0, 1].
    for (size_t i = 0; i < base.texelCount(); ++i) ASSERT_TRUE(base.texel(i).x >= 0.0f && base.texel(i).x <= 1.0f);
    EXPECT_GT(base.average.y, 0.0f);
    EXPECT_NE(m.baseColorTexture.texture, m.metallicRoughnessTexture.texture);
}

TEST(GltfLoader, BundledCornellBoxIsLambertianWithItsCamera) {
    Scene scene = loadGltf(sourcePath("scenes/cornell-box/cornell-box.gltf"));
    EXPECT_EQ(scene.mesh.triangleCount(), 32u);  // 5 walls + light (12) and two blocks of 5 quads (20)
    ASSERT_EQ(scene.cameras.size(), 1u);
    EXPECT_NEAR(scene.cameras[0].position.z, -0.8f, 1e-6f);
    // The camera looks down +Z (its -Z axis turned 180 degrees).
    EXPECT_NEAR(scene.cameras[0].worldFromCamera[2].z, -1.0f, 1e-6f);
    int emitters = 0;
    for (const Material& m : scene.materials) {
        EXPECT_EQ(m.specular, 0.0f) << m.name;
        EXPECT_EQ(m.metallic, 0.0f) << m.name;
        if (m.emissive()) {
            ++emitters;
            EXPECT_FLOAT_EQ(m.emission.x, 17.0f);
            EXPECT_FLOAT_EQ(m.emission.y, 12.0f);
            EXPECT_FLOAT_EQ(m.emission.z, 4.0f);
        }
    }
    EXPECT_EQ(emitters, 1);
}

TEST(GltfLoader, DegenerateTrianglesAreDroppedAndCounted) {
    Scene scene = loadGltf(sourcePath("tests/data/valid/degenerate-triangle.gltf"));
    EXPECT_EQ(scene.stats.trianglesRead, 2u);
    EXPECT_EQ(scene.stats.degenerateTrianglesDropped, 1u);
    EXPECT_EQ(scene.mesh.triangleCount(), 1u);
    // No NORMAL attribute: flat normals generated from the winding (+Z here).
    EXPECT_EQ(scene.stats.primitivesWithGeneratedNormals, 1u);
    EXPECT_FLOAT_EQ(scene.mesh.normals[0].z, 1.0f);
    // No material: the glTF default (white, metallic 1, roughness 1).
    ASSERT_EQ(scene.materials.size(), 1u);
    EXPECT_EQ(scene.materials[0].metallic, 1.0f);
}

TEST(GltfLoader, MissingFileIsASceneError) {
    try {
        loadGltf("/nonexistent/scene.gltf");
        FAIL() << "expected SceneError";
    } catch (const SceneError& e) {
        EXPECT_NE(std::string(e.what()).find("/nonexistent/scene.gltf: cannot open file"), std::string::npos);
    }
}

}  // namespace
}  // namespace nrad
