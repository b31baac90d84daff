// Scene loading shared by the commands: one message format and exit code for unusable scenes.
#include <cstdio>

#include "baker/cmd/commands.h"
#include "baker/scene/gltf_loader.h"

namespace nrad {

namespace {

void printImportSummary(const Scene& scene) {
    const ImportStats& s = scene.stats;
    std::fprintf(stderr, "scene: %s: %zu triangles (%zu read, %zu degenerate dropped), %zu materials, %zu textures, "
                         "%zu emissive triangles, %zu punctual lights, %zu cameras\n",
                 scene.sourcePath.c_str(), scene.mesh.triangleCount(), s.trianglesRead, s.degenerateTrianglesDropped,
                 scene.materials.size(), scene.textures.size(), scene.emissiveTriangleCount(), scene.lights.size(),
                 scene.cameras.size());
    for (const std::string& w : s.warnings) std::fprintf(stderr, "warning: %s: %s\n", scene.sourcePath.c_str(), w.c_str());
}

}  // namespace

int loadSceneForCommand(const char* command, const std::string& path, bool quiet, Scene& scene) {
    try {
        scene = loadGltf(path);
    } catch (const SceneError& e) {
        std::fprintf(stderr, "nrad %s: %s\n", command, e.what());
        return kExitBadInput;
    }
    if (!quiet) printImportSummary(scene);
    if (scene.mesh.triangleCount() == 0) {
        std::fprintf(stderr, "nrad %s: %s: the scene has no triangles\n", command, path.c_str());
        return kExitBadInput;
    }
    return kExitOk;
}

int chooseCameraForCommand(const char* command, const Scene& scene, int index, bool quiet, Camera& camera) {
    if (index >= 0) {
        if (size_t(index) >= scene.cameras.size()) {
            std::fprintf(stderr, "nrad %s: --camera %d: %s has %zu camera(s)\n", command, index, scene.sourcePath.c_str(),
                         scene.cameras.size());
            return kExitUsage;
        }
        camera = scene.cameras[size_t(index)];
    } else if (!scene.cameras.empty()) {
        camera = scene.cameras.front();
    } else {
        camera = frameBounds(scene.bounds);
        if (!quiet) std::fprintf(stderr, "camera: the scene has none; framing its bounds from +Z\n");
    }
    return kExitOk;
}

}  // namespace nrad
