// Environment: light arriving from infinitely far away in every direction a ray leaves the scene by: a
// constant sky colour or an equirectangular (latitude-longitude) HDR map, with an intensity and a rotation
// about the up axis (+Y, glTF's up). Importance sampling lives with the renderer (lights/environment_light.h);
// this is the description and its exact radiance lookup, shared by every renderer.
//
// Map convention (docs/lights.md): a world direction d, after undoing the rotation, has polar angle
// theta = acos(d.y) from +Y and azimuth phi = atan2(d.x, -d.z); u = 0.5 + phi / 2pi (the map's centre column
// lies towards -Z, what the auto-framing camera looks at), v = theta / pi (the top row is straight up). The
// radiance is piecewise constant over texels (nearest texel, no filtering), so an importance sampler built
// from the texels draws exactly the function it is weighted by.
#pragma once

#include <stdexcept>
#include <string>
#include <vector>

#include <glm/glm.hpp>

namespace nrad {

struct Environment {
    enum class Kind { None, Constant, Map };
    Kind kind = Kind::None;
    glm::vec3 color{0.0f};  // Constant: radiance (before intensity)
    int width = 0, height = 0;  // Map
    std::vector<glm::vec3> texels;  // Map: linear radiance, row-major, top row (+Y) first
    float intensity = 1.0f;  // multiplies every value
    float rotationDegrees = 0.0f;  // about +Y, counter-clockwise seen from above
    std::string source;  // what the user gave: a file, "r,g,b", or "default sky"
    bool isDefault = false;  // the default sky of a scene without lights of its own

    bool active() const;
    // Radiance arriving at any point from direction `towards` (unit, world space), i.e. travelling along
    // -towards. Zero when inactive.
    glm::vec3 radiance(const glm::vec3& towards) const;
    // World direction <-> map coordinates in [0, 1]^2 (rotation applied).
    glm::vec2 mapCoordinates(const glm::vec3& towards) const;
    glm::vec3 direction(glm::vec2 uv) const;
    // The mean radiance over the sphere of directions (solid-angle weighted), per channel.
    glm::vec3 meanRadiance() const;
    // A one-line description for messages and metadata.
    std::string describe() const;
};

// The default sky of a scene that has no light of its own: constant radiance 1 (a white furnace sky).
Environment defaultSky();

// Parses what `--environment` accepts: "none", "r,g,b" (radiance, finite, >= 0), or a path to an .exr or
// .hdr equirectangular map (width = 2 x height is usual but not required). Throws EnvironmentSpecError for a
// bad value, SceneError naming the file and what is wrong with it. Non-finite or negative texels are an error,
// not clamped.
// Thrown by parseEnvironment for a flag value that is not an environment at all (r,g,b not finite and >= 0,
// a non-finite intensity or angle): a usage error (exit 2), where a bad map file is a bad input (exit 3).
class EnvironmentSpecError : public std::runtime_error {
public:
    using std::runtime_error::runtime_error;
};
Environment parseEnvironment(const std::string& spec, float intensity = 1.0f, float rotationDegrees = 0.0f);

}  // namespace nrad
