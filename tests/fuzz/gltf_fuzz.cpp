// Fuzz target for the glTF importer (.gltf text and .glb): any bytes are imported with external files
// forbidden (the input is all there is) and limits small enough for the fuzzer's memory. Refusing with a
// SceneError is the expected outcome for most inputs; a crash, a sanitizer report, any other exception, or
// a scene that breaks the importer's promises (indices in range, finite geometry, materials that exist)
// is a bug. Built by tests/fuzz/CMakeLists.txt (clang, libFuzzer, ASan, UBSan); seeded from tests/data, the
// bundled scenes and the hostile inputs of issue 37 (tests/fuzz/gltf-corpus).
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <vector>

#include "baker/scene/gltf_loader.h"

namespace {

void require(bool ok, const char* what) {
    if (!ok) {
        std::fprintf(stderr, "gltf_fuzz: imported scene breaks a promise: %s\n", what);
        std::abort();
    }
}

bool finite(const glm::vec3& v) { return std::isfinite(v.x) && std::isfinite(v.y) && std::isfinite(v.z); }

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
    nrad::ImportLimits limits;
    limits.maxTexturePixels = 1u << 20;  // 1 Mpixel, 1 M triangles: within libFuzzer's 2 GB
    limits.maxTriangles = 1u << 20;
    try {
        const nrad::Scene scene = nrad::loadGltfFromMemory(std::vector<uint8_t>(data, data + size), "fuzz.gltf", limits, false);
        const nrad::TriangleMesh& m = scene.mesh;
        require(!scene.materials.empty(), "no material");
        require(m.triangles.size() == m.materialIds.size(), "a triangle without a material id");
        require(m.triangles.size() <= limits.maxTriangles, "more triangles than the limit");
        require(m.normals.size() == m.positions.size() && m.uv0.size() == m.positions.size(), "attribute counts differ");
        for (size_t t = 0; t < m.triangles.size(); ++t) {
            for (int k = 0; k < 3; ++k) require(m.triangles[t][k] < m.positions.size(), "vertex index out of range");
            require(m.materialIds[t] < scene.materials.size(), "material id out of range");
        }
        for (size_t v = 0; v < m.positions.size(); ++v) require(finite(m.positions[v]) && finite(m.normals[v]), "non-finite vertex");
        for (const nrad::Texture& tex : scene.textures)
            require(uint64_t(tex.width) * uint64_t(tex.height) <= limits.maxTexturePixels, "texture beyond the limit");
    } catch (const nrad::SceneError&) {
        // refused with a message: what a bad file should get
    }
    return 0;
}
