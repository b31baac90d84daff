// SurfaceInteraction: what the integrator knows about a ray hit: position, normals, texture
// coordinates, the material evaluated there (textures applied) and the emitted radiance.
#pragma once

#include <glm/glm.hpp>
#include <nrad/eval.h>

#include "baker/render/accel.h"
#include "baker/render/bsdf.h"
#include "baker/scene/material_lookup.h"
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
    float margin = 0.0f;  // triangleMargin of the triangle hit

    // Rays leave the surface from p itself, so their geometry is exact (an origin moved off the surface
    // sees every emitter from a slightly different place, a bias of about the offset / distance: 0.5% at
    // 0.2 m from a light 100 m from the origin; issue 12). Hits closer than this distance along w are not
    // taken: those within `margin` of the surface's plane, where the surface itself could be found again.
    float spawnDistance(const glm::vec3& w) const;
};

// The material terms of the evaluation contract (nrad/eval.h) at an interaction: what an engine's G-buffer
// holds there.
eval::Surface shadingSurface(const SurfaceInteraction& si);

// Asks the memory system for the texels makeInteraction will read for this hit (a hint: lookups into large
// textures miss the caches nearly every time, and a lookup is too long for the processor to overlap the
// misses of several on its own, so a batch prefetches all its hits' texels before making any of them).
void prefetchInteraction(const Scene& scene, const Hit& hit);

// Builds the interaction for a hit of a ray travelling along `direction` (into `si`: every member written).
void makeInteraction(const Scene& scene, const Hit& hit, const glm::vec3& direction, SurfaceInteraction& si);
inline SurfaceInteraction makeInteraction(const Scene& scene, const Hit& hit, const glm::vec3& direction) {
    SurfaceInteraction si;
    makeInteraction(scene, hit, direction, si);
    return si;
}

}  // namespace nrad
