// glTF 2.0 import (.gltf and .glb, Draco, punctual lights, emissive strength, specular): the only
// module that sees tinygltf and Draco. Everything it returns is the project's own Scene.
#pragma once

#include <cstddef>
#include <cstdint>
#include <stdexcept>
#include <string>
#include <vector>

#include "baker/scene/scene.h"

namespace nrad {

// A scene file the user gave us is unusable. The message names the file and what is wrong.
class SceneError : public std::runtime_error {
public:
    using std::runtime_error::runtime_error;
};

// What one scene may ask of the machine. A file is small and what it describes can be huge (a 348 KB file
// holding a 16384 x 16384 PNG, a node graph that instances a mesh 2^29 times): the importer refuses a scene
// beyond these limits, before allocating for it, with a message naming the limit and its flag.
struct ImportLimits {
    // Pixels of one image (width x height), checked from the image's header before it is decoded.
    // Default 8192 x 8192 (256 MiB as 8-bit RGBA); `--max-texture-pixels`.
    uint64_t maxTexturePixels = uint64_t(8192) * 8192;
    // Triangles of the whole flattened scene (every mesh instance counted); the vertices emitted may be at
    // most three times this. Default 50 million (about 8 GB of scene and BVH); `--max-triangles`.
    uint64_t maxTriangles = 50'000'000;
};

// Loads a glTF 2.0 file into a flattened world-space Scene. Throws SceneError on any problem with the
// input (unreadable or truncated file, unsupported required extension, missing buffer, index or byte range
// out of range, a size that overflows, non-finite vertex, a node graph glTF forbids, a limit exceeded, ...).
// Degenerate triangles are dropped and counted in stats.
Scene loadGltf(const std::string& path, const ImportLimits& limits = {});

// The same from the file's bytes already in memory (.gltf text or .glb); `path` names the file in messages
// and its directory resolves relative URIs. `allowExternalFiles` false refuses every URI that is not a
// data URI (the fuzzer's setting: the input is all there is).
Scene loadGltfFromMemory(const std::vector<uint8_t>& bytes, const std::string& path, const ImportLimits& limits = {},
                         bool allowExternalFiles = true);

}  // namespace nrad
