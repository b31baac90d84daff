// Scene loading shared by the commands: one message format and exit code for unusable scenes.
#include <cmath>
#include <cstdio>

#include <nlohmann/json.hpp>

#include "baker/bake/baker.h"
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

void addEnvironmentOptions(CLI::App* cmd, EnvironmentOptions& o) {
    cmd->add_option("--environment", o.spec,
                    "Light from outside the scene: none, a constant sky radiance r,g,b, or an equirectangular HDR map "
                    "(.exr or .hdr). Default: the scene's own lights; a scene without any gets the default sky (1,1,1)");
    cmd->add_option("--environment-intensity", o.intensity, "Multiplies the environment (default 1)")
        ->check(CLI::Range(0.0f, 1e30f));
    cmd->add_option("--environment-rotation", o.rotationDegrees,
                    "Rotates the environment map about +Y, degrees counter-clockwise seen from above (default 0)")
        ->check(CLI::Range(-1e6f, 1e6f));
}

int applyEnvironmentForCommand(const char* command, CLI::App* cmd, const EnvironmentOptions& o, bool quiet, Scene& scene,
                               const std::string& recordedMetadata) {
    const bool given = cmd->count("--environment") > 0;
    if (!given && (cmd->count("--environment-intensity") > 0 || cmd->count("--environment-rotation") > 0)) {
        std::fprintf(stderr, "nrad %s: --environment-intensity and --environment-rotation need --environment\n", command);
        return kExitUsage;
    }
    try {
        if (given) {
            scene.environment = parseEnvironment(o.spec, o.intensity, o.rotationDegrees);
        } else if (!recordedMetadata.empty()) {
            nlohmann::json meta = nlohmann::json::parse(recordedMetadata, nullptr, false);
            const nlohmann::json* env = nullptr;
            if (meta.is_object() && meta.contains("bake") && meta["bake"].is_object() && meta["bake"].contains("environment"))
                env = &meta["bake"]["environment"];
            if (env && env->is_object()) {
                std::string kind = env->value("kind", "none");
                if (kind == "constant" && env->value("default", false)) {
                    scene.environment = defaultSky();
                } else if (kind == "constant" || kind == "map") {
                    std::string spec = env->value("source", "");
                    scene.environment = parseEnvironment(spec, env->value("intensity", 1.0f), env->value("rotation_degrees", 0.0f));
                }
                if (!quiet && scene.environment.active())
                    std::fprintf(stderr, "environment: %s (as the asset recorded)\n", scene.environment.describe().c_str());
                return kExitOk;
            }
        }
    } catch (const SceneError& e) {
        std::fprintf(stderr, "nrad %s: %s\n", command, e.what());
        return kExitBadInput;
    }
    if (!given && !scene.hasLight()) {
        scene.environment = defaultSky();
        if (!quiet)
            std::fprintf(stderr, "environment: %s has no light of its own: lit by the default sky (constant radiance 1; "
                                 "--environment none for none)\n", scene.sourcePath.c_str());
    }
    if (!quiet && given && scene.environment.active())
        std::fprintf(stderr, "environment: %s\n", scene.environment.describe().c_str());
    if (!scene.hasLight() && !quiet)
        std::fprintf(stderr, "warning: %s: nothing lights the scene (no emitter of positive power, no punctual light, no "
                             "environment): every image and every training target is black\n", scene.sourcePath.c_str());
    return kExitOk;
}

int checkAssetSceneForCommand(const char* command, const std::string& assetPath, const std::string& metadata,
                              const Scene& scene, bool force, bool quiet) {
    nlohmann::json meta = metadata.empty() ? nlohmann::json() : nlohmann::json::parse(metadata, nullptr, false);
    if (!meta.is_object() || !meta.contains("scene_hash") || !meta["scene_hash"].is_string()) {
        if (!quiet) std::fprintf(stderr, "warning: %s has no metadata: cannot check that it was baked from %s\n", assetPath.c_str(),
                                 scene.sourcePath.c_str());
        return kExitOk;
    }
    char hash[17];
    std::snprintf(hash, sizeof hash, "%016llx", (unsigned long long)sceneHash(scene));
    const std::string recorded = meta["scene_hash"].get<std::string>();
    if (recorded == hash) return kExitOk;
    if (force) {
        if (!quiet) std::fprintf(stderr, "warning: %s was baked from another scene or lighting (scene hash %s, %s is %s); "
                                         "used anyway (--force)\n", assetPath.c_str(), recorded.c_str(), scene.sourcePath.c_str(), hash);
        return kExitOk;
    }
    std::fprintf(stderr, "nrad %s: %s was baked from another scene or lighting than %s (scene hash %s, this scene %s); "
                         "use the scene and --environment it was baked with, or --force\n",
                 command, assetPath.c_str(), scene.sourcePath.c_str(), recorded.c_str(), hash);
    return kExitBadInput;
}

}  // namespace nrad
