// glTF 2.0 import (.gltf and .glb, Draco, punctual lights, emissive strength, specular): the only
// module that sees tinygltf and Draco. Everything it returns is the project's own Scene.
#pragma once

#include <stdexcept>
#include <string>

#include "baker/scene/scene.h"

namespace nrad {

// A scene file the user gave us is unusable. The message names the file and what is wrong.
class SceneError : public std::runtime_error {
public:
    using std::runtime_error::runtime_error;
};

// Loads a glTF 2.0 file into a flattened world-space Scene. Throws SceneError on any problem with the
// input (unreadable or truncated file, unsupported required extension, missing buffer, index out of
// range, non-finite vertex, node cycle, ...). Degenerate triangles are dropped and counted in stats.
Scene loadGltf(const std::string& path);

}  // namespace nrad
