// Scene loading shared by the commands: one message format and exit code for unusable scenes.
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <string>
#include <system_error>
#include <vector>

#include <nlohmann/json.hpp>

#include "baker/bake/baker.h"
#include "baker/cmd/commands.h"
#include "baker/scene/gltf_loader.h"
#include "baker/util/atomic_file.h"
#include "baker/util/memory.h"

namespace nrad {

namespace {

bool parseVec3(const std::string& s, glm::vec3& v) {
    char rest;
    return std::sscanf(s.c_str(), "%f,%f,%f%c", &v.x, &v.y, &v.z, &rest) == 3 && std::isfinite(v.x) && std::isfinite(v.y) &&
           std::isfinite(v.z);
}

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

int loadSceneForCommand(const char* command, const std::string& path, bool quiet, Scene& scene, const ImportLimits& limits) {
    try {
        scene = loadGltf(path, limits);
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

int insertObjectsForCommand(const char* command, const std::vector<std::string>& specs, const ImportLimits& limits, bool quiet,
                            Scene& scene) {
    for (const std::string& spec : specs) {
        // FILE@x,y,z (the object's own origin moved there), or FILE where it stands in its own file.
        std::string path = spec;
        glm::vec3 offset(0.0f);
        if (const size_t at = spec.rfind('@'); at != std::string::npos && parseVec3(spec.substr(at + 1), offset)) path = spec.substr(0, at);
        else if (std::error_code ec; at != std::string::npos && !std::filesystem::exists(spec, ec)) {
            std::fprintf(stderr, "nrad %s: --insert %s: the position after @ is not x,y,z (three finite numbers)\n", command, spec.c_str());
            return kExitUsage;
        }
        if (scene.mesh.triangleCount() >= limits.maxTriangles) {
            std::fprintf(stderr, "nrad %s: --insert %s: the scene already has %zu triangles, the most --max-triangles allows\n", command,
                         spec.c_str(), scene.mesh.triangleCount());
            return kExitBadInput;
        }
        Scene object;
        try {
            ImportLimits left = limits;
            left.maxTriangles = limits.maxTriangles - scene.mesh.triangleCount();  // what the objects may add
            object = loadGltf(path, left);
            insertObject(scene, object, offset, spec);
        } catch (const SceneError& e) {
            std::fprintf(stderr, "nrad %s: --insert: %s\n", command, e.what());
            return kExitBadInput;
        }
        if (!quiet)
            std::fprintf(stderr, "inserted %s: %zu triangles at %g,%g,%g (not in the bake: shaded through the asset's volume query)\n",
                         path.c_str(), object.mesh.triangleCount(), offset.x, offset.y, offset.z);
    }
    return kExitOk;
}

void addInsertOption(CLI::App* cmd, std::vector<std::string>& specs) {
    cmd->add_option("--insert", specs,
                    "Place an object that was not in the bake: FILE.gltf[@x,y,z] (its origin moved to x,y,z; repeat for several). "
                    "Path traced with the scene; through an asset, shaded by its volume query (bake --volume-points)")
        ->allow_extra_args(false);
}

void addImportSettings(SettingsTable& t, ImportLimits& limits) {
    t.add("--max-texture-pixels", &limits.maxTexturePixels,
          "Refuse a scene with an image of more pixels than this (8192 x 8192 by default), read from its header before decoding")
        .checkedBy([](CLI::Option* p) { p->check(CLI::Range(uint64_t(1), uint64_t(1) << 40)); });
    t.add("--max-triangles", &limits.maxTriangles,
          "Refuse a scene that flattens to more triangles than this, every mesh instance counted")
        .checkedBy([](CLI::Option* p) { p->check(CLI::Range(uint64_t(1), uint64_t(1) << 31)); });
}

void addImportOptions(CLI::App* cmd, ImportLimits& limits) {
    SettingsTable t;
    addImportSettings(t, limits);
    t.addOptions(cmd);
}

int checkOutputsForCommand(const char* command, const std::vector<std::string>& files, const std::vector<std::string>& folders) {
    for (int folder = 0; folder < 2; ++folder)
        for (const std::string& path : folder ? folders : files) {
            const OutputCheck c = folder ? checkOutputFolder(path) : checkOutputFile(path);
            if (c.problem == OutputProblem::kNone) continue;
            std::fprintf(stderr, "nrad %s: %s\n", command, c.message.c_str());
            return c.problem == OutputProblem::kCannotCreate ? kExitIo : kExitUsage;
        }
    return kExitOk;
}

int chooseCameraForCommand(const char* command, const Scene& scene, int index, const ViewOptions& view, bool quiet,
                           Camera& camera) {
    std::string said;
    if (index >= 0) {
        if (size_t(index) >= scene.cameras.size()) {
            std::fprintf(stderr, "nrad %s: --camera %d: %s has %zu camera(s)\n", command, index, scene.sourcePath.c_str(),
                         scene.cameras.size());
            return kExitUsage;
        }
        camera = scene.cameras[size_t(index)];
        said = "the scene's camera " + std::to_string(index) + (camera.name.empty() ? "" : " (" + camera.name + ")");
    } else if (!scene.cameras.empty()) {
        camera = scene.cameras.front();
        said = "the scene's camera 0" + (camera.name.empty() ? "" : " (" + camera.name + ")") + " of " +
               std::to_string(scene.cameras.size()) + " (--camera N for another)";
    } else {
        camera = frameBounds(scene.bounds);
        said = "the scene has none; framing its bounds from +Z, outside them (an interior shows its outer walls: "
               "--look-from and --look-at place a camera inside)";
    }
    // --look-from/--look-at replace the chosen camera (keeping its field of view): then only they are said
    if (!view.lookFrom.empty() && !view.lookAt.empty()) said = "--look-from " + view.lookFrom + " --look-at " + view.lookAt;
    if (int code = applyViewForCommand(command, view, camera)) return code;
    if (!quiet) std::fprintf(stderr, "camera: %s\n", said.c_str());
    return kExitOk;
}

int imageSizeForCommand(const char* command, int width, int height, float aspect, int defaultWidth, int& outWidth,
                        int& outHeight) {
    constexpr double kMaxSide = 32768.0;
    const double w = width > 0 ? width : height > 0 ? std::max(1.0, std::round(height * double(aspect))) : defaultWidth;
    const double h = height > 0 ? height : std::max(1.0, std::round(w / double(aspect)));
    if (!(w <= kMaxSide && h <= kMaxSide)) {
        std::fprintf(stderr, "nrad %s: the camera's aspect ratio %g makes the image %.0f x %.0f, more than 32768 on a side; "
                             "give both --width and --height\n", command, double(aspect), w, h);
        return kExitUsage;
    }
    outWidth = int(w);
    outHeight = int(h);
    return kExitOk;
}

int checkMemoryForCommand(const char* command, uint64_t bytes, const std::string& what) {
    const uint64_t available = availableMemoryBytes();
    if (bytes <= available) return kExitOk;
    std::fprintf(stderr, "nrad %s: %s needs about %s; this process can allocate %s now (free memory, container and ulimit): "
                         "ask for less\n", command, what.c_str(), gibibytes(bytes).c_str(), gibibytes(available).c_str());
    return kExitUsage;
}

CLI::Validator finiteRange(double lo, double hi) {
    const std::string range = "[" + CLI::detail::to_string(lo) + " - " + CLI::detail::to_string(hi) + "]";
    return CLI::Validator(
        [lo, hi, range](std::string& text) -> std::string {
            char* end = nullptr;
            const double v = std::strtod(text.c_str(), &end);
            if (end == text.c_str() || *end != '\0' || !std::isfinite(v)) return "Value " + text + " is not a finite number";
            if (v < lo || v > hi) return "Value " + text + " not in range " + range;
            return {};
        },
        "FLOAT in " + range);
}

std::vector<std::string> splitCommas(const std::string& s) {
    std::vector<std::string> parts;
    size_t at = 0;
    for (size_t comma; (comma = s.find(',', at)) != std::string::npos; at = comma + 1) parts.push_back(s.substr(at, comma - at));
    parts.push_back(s.substr(at));
    return parts;
}

void addViewOptions(CLI::App* cmd, ViewOptions& o) {
    cmd->add_option("--look-from", o.lookFrom, "Camera position x,y,z (with --look-at: overrides the scene's camera)");
    cmd->add_option("--look-at", o.lookAt, "Point the camera looks at, x,y,z");
    cmd->add_option("--up", o.up, "Up direction for --look-from/--look-at (default 0,1,0)");
    cmd->add_option("--fov", o.fovDegrees, "Vertical field of view in degrees")->check(finiteRange(0.01, 179.0));
}

int applyViewForCommand(const char* command, const ViewOptions& o, Camera& camera) {
    if (o.lookFrom.empty() != o.lookAt.empty()) {
        std::fprintf(stderr, "nrad %s: --look-from and --look-at go together\n", command);
        return kExitUsage;
    }
    if (!o.lookFrom.empty()) {
        glm::vec3 from, at, up;
        if (!parseVec3(o.lookFrom, from) || !parseVec3(o.lookAt, at) || !parseVec3(o.up, up)) {
            std::fprintf(stderr, "nrad %s: --look-from, --look-at and --up take x,y,z (finite numbers)\n", command);
            return kExitUsage;
        }
        glm::vec3 back = from - at;
        glm::vec3 right = glm::cross(up, back);
        if (!(glm::length(back) > 0.0f) || !(glm::length(right) > 1e-6f * glm::length(up) * glm::length(back))) {
            std::fprintf(stderr, "nrad %s: --look-from equals --look-at, or --up is parallel to the view\n", command);
            return kExitUsage;
        }
        back = glm::normalize(back);
        right = glm::normalize(right);
        Camera c;
        c.name = "--look-from";
        c.position = from;
        c.worldFromCamera = glm::mat3(right, glm::cross(back, right), back);
        c.yfov = camera.type == Camera::Type::Perspective ? camera.yfov : 0.6911f;
        camera = c;
    }
    if (o.fovDegrees > 0.0f) {
        camera.type = Camera::Type::Perspective;
        camera.yfov = o.fovDegrees * 3.14159265358979323846f / 180.0f;
    }
    return kExitOk;
}

void addLightingSettings(SettingsTable& t, LightingOptions& o) {
    t.add("--environment", &o.environment,
          "Light from outside the scene: none, a constant sky radiance r,g,b, or an equirectangular HDR map (.exr or .hdr). "
          "Not given: the scene's own lights; a scene without any gets the default sky (1,1,1)");
    t.add("--environment-intensity", &o.intensity, "Multiplies the environment")
        .checkedBy([](CLI::Option* p) { p->check(finiteRange(0.0, 1e30)); });
    t.add("--environment-rotation", &o.rotationDegrees,
          "Rotates the environment map about +Y, degrees counter-clockwise seen from above")
        .checkedBy([](CLI::Option* p) { p->check(finiteRange(-1e6, 1e6)); });
    t.add("--sun", &o.sun, "Adds a sun: x,y,z the direction towards it (world space, +Y up)");
    t.add("--sun-illuminance", &o.sunIlluminance, "The sun's illuminance in lux")
        .checkedBy([](CLI::Option* p) { p->check(finiteRange(0.0, 1e12)); });
    t.add("--sun-angle", &o.sunAngle,
          "The sun's angular diameter in degrees for soft shadows, 0: sharp (0.53 is the real sun's)")
        .checkedBy([](CLI::Option* p) { p->check(finiteRange(0.0, 30.0)); });
    t.add("--runtime-direct", &o.runtimeDirect,
          "Mixed lighting: lights whose direct light the engine draws at run time (the asset holds only their indirect "
          "light): auto (every sharp punctual light and a sharp sun), none (bake it all), all (every punctual light and "
          "the sun), sun, or comma-separated light names or indices");
}

void addLightingOptions(CLI::App* cmd, LightingOptions& o) {
    SettingsTable t;
    addLightingSettings(t, o);
    t.addOptions(cmd);
}

bool lightingFlagsGiven(CLI::App* cmd) {
    for (const char* f : {"--environment", "--environment-intensity", "--environment-rotation", "--sun", "--sun-illuminance",
                          "--sun-angle", "--runtime-direct"})
        if (cmd->count(f) > 0) return true;
    return false;
}

namespace {


// Applies explicit options (not the recorded ones). Returns an exit code; fills `record`.
int applyOptions(const char* command, const LightingOptions& o, bool environmentGiven, bool quiet, Scene& scene,
                 nlohmann::json& record) {
    if (!environmentGiven && (o.intensity != 1.0f || o.rotationDegrees != 0.0f)) {
        std::fprintf(stderr, "nrad %s: --environment-intensity and --environment-rotation need --environment\n", command);
        return kExitUsage;
    }
    if (!o.sun.empty()) {
        glm::vec3 towards;
        if (!parseVec3(o.sun, towards) || !(glm::dot(towards, towards) > 0.0f)) {
            std::fprintf(stderr, "nrad %s: --sun %s: expected x,y,z, a finite non-zero direction towards the sun\n", command,
                         o.sun.c_str());
            return kExitUsage;
        }
        if (!(o.sunIlluminance >= 0.0f) || !(o.sunAngle >= 0.0f && o.sunAngle <= 30.0f)) {
            std::fprintf(stderr, "nrad %s: --sun-illuminance must be >= 0 and --sun-angle 0..30 degrees\n", command);
            return kExitUsage;
        }
        PunctualLight sun;
        sun.type = PunctualLight::Type::Directional;
        sun.name = "sun";
        sun.direction = -glm::normalize(towards);
        sun.intensity = glm::vec3(o.sunIlluminance / kLumensPerWatt);
        sun.cosAngularRadius = o.sunAngle > 0.0f ? float(std::cos(0.5 * double(o.sunAngle) * 3.14159265358979323846 / 180.0)) : 1.0f;
        scene.lights.push_back(sun);
        record["sun"] = {towards.x, towards.y, towards.z};
        record["sun_illuminance"] = o.sunIlluminance;
        record["sun_angle"] = o.sunAngle;
        if (!quiet)
            std::fprintf(stderr, "sun: towards %g,%g,%g, %g lux (%g W/m^2), %s\n", double(towards.x), double(towards.y), double(towards.z),
                         double(o.sunIlluminance), double(o.sunIlluminance / kLumensPerWatt),
                         o.sunAngle > 0.0f ? ("soft, " + std::to_string(o.sunAngle) + " degrees across").c_str() : "sharp");
    }
    try {
        if (environmentGiven) {
            scene.environment = parseEnvironment(o.environment, o.intensity, o.rotationDegrees);
            if (!quiet && scene.environment.active())
                std::fprintf(stderr, "environment: %s\n", scene.environment.describe().c_str());
        }
    } catch (const EnvironmentSpecError& e) {
        std::fprintf(stderr, "nrad %s: %s\n", command, e.what());
        return kExitUsage;
    } catch (const SceneError& e) {
        std::fprintf(stderr, "nrad %s: %s\n", command, e.what());
        return kExitBadInput;
    }
    if (!o.runtimeDirect.empty()) {
        std::vector<std::string> names = splitCommas(o.runtimeDirect);
        size_t marked = 0;
        for (const std::string& n : names) {
            // auto: every sharp light, none: no light (neither is an error where the scene has no such light).
            bool found = n == "auto" || n == "none";
            for (size_t i = 0; i < scene.lights.size(); ++i) {
                PunctualLight& l = scene.lights[i];
                bool match = n == "all" || (n == "sun" && l.type == PunctualLight::Type::Directional) || n == l.name ||
                             n == std::to_string(i) || (n == "auto" && !l.soft());
                if (!match) continue;
                ++marked;
                found = true;
                if (l.soft()) {
                    std::fprintf(stderr, "nrad %s: --runtime-direct %s: light %zu (%s) is soft; an engine draws sharp lights "
                                         "(--sun-angle 0)\n", command, n.c_str(), i, l.name.c_str());
                    return kExitUsage;
                }
                l.runtimeDirect = true;
            }
            if (!found) {
                std::fprintf(stderr, "nrad %s: --runtime-direct %s: the scene has no such punctual light (%zu lights)\n",
                             command, n.c_str(), scene.lights.size());
                return kExitUsage;
            }
        }
        // Recorded when it marked a light (an asset without engine-drawn lights keeps its bytes).
        if (marked > 0) record["runtime_direct"] = o.runtimeDirect;
    }
    return kExitOk;
}

}  // namespace

int applyLightingForCommand(const char* command, const LightingOptions& options, bool anyFlagGiven, bool environmentGiven,
                            bool quiet, Scene& scene, const std::string& recordedMetadata, std::string* lightingJson) {
    LightingOptions o = options;
    bool fromAsset = false;
    if (!anyFlagGiven && !recordedMetadata.empty()) {
        // Replay what the asset recorded: its environment and its command-line lighting.
        nlohmann::json meta = nlohmann::json::parse(recordedMetadata, nullptr, false);
        const nlohmann::json bake = meta.is_object() ? meta.value("bake", nlohmann::json()) : nlohmann::json();
        if (bake.is_object() && bake.contains("environment") && bake["environment"].is_object()) {
            fromAsset = true;
            const nlohmann::json& env = bake["environment"];
            const std::string kind = env.value("kind", "none");
            environmentGiven = !(kind == "constant" && env.value("default", false));
            o.environment = kind == "none" ? "none" : env.value("source", "none");
            o.intensity = env.value("intensity", 1.0f);
            o.rotationDegrees = env.value("rotation_degrees", 0.0f);
            const nlohmann::json lighting = bake.value("lighting", nlohmann::json::object());
            if (lighting.is_object()) {
                if (lighting.contains("sun") && lighting["sun"].is_array() && lighting["sun"].size() == 3) {
                    char b[96];
                    std::snprintf(b, sizeof b, "%.9g,%.9g,%.9g", lighting["sun"][0].get<double>(), lighting["sun"][1].get<double>(),
                                  lighting["sun"][2].get<double>());
                    o.sun = b;
                    o.sunIlluminance = lighting.value("sun_illuminance", o.sunIlluminance);
                    o.sunAngle = lighting.value("sun_angle", o.sunAngle);
                }
                o.runtimeDirect = lighting.value("runtime_direct", std::string());
            }
            if (!quiet) std::fprintf(stderr, "lighting: as the asset recorded\n");
        }
    }
    nlohmann::json record = nlohmann::json::object();
    if (int code = applyOptions(command, o, environmentGiven, quiet || fromAsset, scene, record)) return code;
    if (!environmentGiven && !scene.hasLight()) {
        scene.environment = defaultSky();
        if (!quiet)
            std::fprintf(stderr, "environment: %s has no light of its own: lit by the default sky (constant radiance 1; "
                                 "--environment none for none)\n", scene.sourcePath.c_str());
    }
    else if (!environmentGiven && !quiet && !fromAsset) {
        // The default sky is off because the scene has light of its own: say so every time, with what that light
        // is (a model lit only by an emissive texture, or a --sun, otherwise renders dark without a word).
        size_t punctual = 0, sun = 0;
        for (const PunctualLight& l : scene.lights) (l.name == "sun" && !o.sun.empty() ? sun : punctual) += 1;
        std::fprintf(stderr, "lighting: %s's own light (%zu emissive triangles, %zu punctual lights%s), no environment; the "
                             "default sky lights only scenes without light of their own (--environment 1,1,1 adds it)\n",
                     scene.sourcePath.c_str(), scene.emissiveTriangleCount(), punctual, sun ? ", and the --sun" : "");
    }
    if (!scene.hasLight() && !quiet)
        std::fprintf(stderr, "warning: %s: nothing lights the scene (no emitter of positive power, no punctual light, no "
                             "environment): every image and every training target is black\n", scene.sourcePath.c_str());
    if (lightingJson) *lightingJson = record.empty() ? std::string() : record.dump();
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
