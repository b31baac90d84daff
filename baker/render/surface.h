// SurfaceInteraction: what the integrator knows about a ray hit: position, normals, texture
// coordinates, the material evaluated there (textures applied) and the emitted radiance.
#pragma once

#include <glm/glm.hpp>

#include "baker/render/accel.h"
#include "baker/render/bsdf.h"
#include "baker/scene/scene.h"

namespace nrad {

struct SurfaceInteraction {
    glm::vec3 p{0.0f};
    glm::vec3 ng{0.0f};  // geometric normal, flipped to the side of wo
    glm::vec3 ns{0.0f};  // shading normal, on the same side as ng and wo
    glm::vec3 wo{0.0f};
    bool frontFace = true;  // wo is on the side the winding order's normal points to
    uint32_t triangle = 0;
    const Material* material = nullptr;
    BsdfParams bsdf;
    glm::vec3 emission{0.0f};  // radiance emitted towards wo (zero for a single-sided back face)

    // Offsets the origin of a ray leaving along w so it does not re-hit this surface.
    glm::vec3 spawnOrigin(const glm::vec3& w) const;
};

// Emitted radiance of a triangle at barycentrics (u, v), seen from a direction on the side `front`.
glm::vec3 emittedRadiance(const Scene& scene, uint32_t triangle, float u, float v, bool front);

// Builds the interaction for a hit of a ray travelling along `direction`.
SurfaceInteraction makeInteraction(const Scene& scene, const Hit& hit, const glm::vec3& direction);

// Offset that keeps a spawned ray off the surface at p; relative to the coordinates' magnitude so it
// works at any scene scale.
float rayOffset(const glm::vec3& p);

}  // namespace nrad
