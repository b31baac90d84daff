// glTF import: the external scenes load with the triangle counts of their SOURCES.md (Draco included),
// materials, emission and punctual lights come through with the right values, edge cases are handled.
#include "baker/scene/gltf_loader.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <fstream>
#include <functional>
#include <iterator>

#include <sys/stat.h>

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

std::vector<uint8_t> fileBytes(const std::string& path) {
    std::ifstream f(path, std::ios::binary);
    return std::vector<uint8_t>((std::istreambuf_iterator<char>(f)), std::istreambuf_iterator<char>());
}

std::string errorOf(const std::function<void()>& load) {
    try {
        load();
    } catch (const SceneError& e) {
        return e.what();
    }
    return "(no SceneError)";
}

// Import limits (issue 37): a scene that flattens to more triangles than the limit, or holds a larger image,
// is refused with the limit and its flag named; at the limit it loads.
TEST(GltfLoader, LimitsOnTrianglesAndImagePixelsAreEnforced) {
    const std::string box = sourcePath("scenes/cornell-box/cornell-box.gltf");
    const size_t triangles = loadGltf(box).stats.trianglesRead;
    ImportLimits limits;
    limits.maxTriangles = triangles;
    EXPECT_EQ(loadGltf(box, limits).stats.trianglesRead, triangles);
    limits.maxTriangles = triangles - 1;
    const std::string e = errorOf([&] { loadGltf(box, limits); });
    EXPECT_NE(e.find(box + ": "), std::string::npos) << e;
    EXPECT_NE(e.find("exceeds " + std::to_string(triangles - 1) + " triangles"), std::string::npos) << e;
    EXPECT_NE(e.find("--max-triangles"), std::string::npos) << e;

    // The Avocado's textures are 2048 x 2048: refused from their headers below that, loaded at it.
    const std::string avocado = externalScene("AvocadoDraco/glTF-Draco/Avocado.gltf");
    ImportLimits pixels;
    pixels.maxTexturePixels = 2048 * 2048;
    EXPECT_GT(loadGltf(avocado, pixels).textures.size(), 0u);
    pixels.maxTexturePixels = 2048 * 2048 - 1;
    const std::string t = errorOf([&] { loadGltf(avocado, pixels); });
    EXPECT_NE(t.find("is 2048 x 2048 pixels, more than the limit of 4194303 (--max-texture-pixels)"), std::string::npos) << t;
}

// The hostile files of issue 37 are refused fast and without touching memory outside their buffers (the fuzz
// build runs the same files under ASan): a 16384 x 16384 image is refused from its header, not decoded; a node
// graph that would flatten to 2^30 instances is refused before one is made.
TEST(GltfLoader, HostileSizesAreRefusedBeforeAnyWork) {
    const auto t0 = std::chrono::steady_clock::now();
    for (const char* name : {"huge-image.gltf", "node-dag.gltf", "accessor-count-wraps.gltf", "accessor-offset-wraps.gltf",
                             "bytestride-wraps.gltf"}) {
        const std::string path = sourcePath(std::string("tests/data/malformed/") + name);
        EXPECT_NE(errorOf([&] { loadGltf(path); }).find(path + ": "), std::string::npos) << name;
    }
    // Before the fix: 13 s for the image, 49 s for the graph (and gigabytes). Loose: a slow machine passes.
    EXPECT_LT(std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count(), 5.0);
}

// From memory: the same scene as from the file; with external files forbidden, a buffer URI is refused; and a
// URI naming something that is not a regular file (a FIFO would block the import forever) is refused.
TEST(GltfLoader, FromMemoryAndExternalFiles) {
    const std::string glb = externalScene("CornellBox/CornellBox.glb");
    const Scene a = loadGltf(glb), b = loadGltfFromMemory(fileBytes(glb), glb);
    EXPECT_EQ(a.mesh.positions, b.mesh.positions);
    EXPECT_EQ(a.mesh.triangles, b.mesh.triangles);

    const std::string missing = sourcePath("tests/data/malformed/missing-buffer.gltf");
    EXPECT_NE(errorOf([&] { loadGltf(missing); }).find("does-not-exist.bin"), std::string::npos);
    const std::string dir = test::temporaryDirectory();
    const std::vector<uint8_t> missingBytes = fileBytes(missing);
    std::string text(missingBytes.begin(), missingBytes.end());
    const std::string fifo = dir + "/pipe.bin";
    ASSERT_EQ(::mkfifo(fifo.c_str(), 0600), 0);
    text.replace(text.find("does-not-exist.bin"), std::string("does-not-exist.bin").size(), "pipe.bin");
    const std::string scene = dir + "/fifo.gltf";
    std::ofstream(scene) << text;
    const std::string e = errorOf([&] { loadGltf(scene); });  // returns: never opens the FIFO
    EXPECT_NE(e.find("pipe.bin"), std::string::npos) << e;

    const std::string box = sourcePath("tests/data/valid/byte-indices.gltf");  // data URIs only: loads either way
    EXPECT_EQ(loadGltfFromMemory(fileBytes(box), box, {}, false).mesh.triangleCount(), 1u);
    std::ofstream(dir + "/pipe-free.bin", std::ios::binary) << std::string(36, '\0');
    text.replace(text.find("pipe.bin"), std::string("pipe.bin").size(), "pipe-free.bin");
    const std::vector<uint8_t> bytes(text.begin(), text.end());
    EXPECT_NE(errorOf([&] { loadGltfFromMemory(bytes, dir + "/x.gltf", {}, false); }).find("pipe-free.bin"), std::string::npos);
}

}  // namespace
}  // namespace nrad
