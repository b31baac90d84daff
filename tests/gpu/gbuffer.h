// What an engine's G-buffer holds per pixel, in the runtime's layout: the first hit's position, shading
// normal (on the viewer's side), direction towards the viewer (interleaved xyz) and material terms
// (NradSurface). renderGBuffer fills it from a scene's camera with the baker's ray caster: one ray through
// every pixel centre, as `nrad render --asset` shades with --spp 1 at the same pixels' first hits.
#pragma once

#include <nrad/nrad.h>

#include <vector>

#include <glm/glm.hpp>

#include "baker/render/accel.h"
#include "baker/scene/scene.h"

namespace nrad {

struct GBuffer {
    std::vector<float> positions, normals, directions;
    std::vector<NradSurface> surfaces;
    std::vector<uint32_t> pixel;  // y x width + x of each entry (renderGBuffer); pixels without a hit have none
    int width = 0, height = 0;

    size_t count() const { return surfaces.size(); }
    void add(const glm::vec3& p, const glm::vec3& n, const glm::vec3& d, const NradSurface& s) {
        for (int k = 0; k < 3; ++k) {
            positions.push_back(p[k]);
            normals.push_back(n[k]);
            directions.push_back(d[k]);
        }
        surfaces.push_back(s);
    }
};

// The camera `nrad render` uses by default: the scene's first, or one framing its bounds.
Camera defaultCamera(const Scene& scene);

GBuffer renderGBuffer(const Scene& scene, const Accel& accel, int width, int height);

}  // namespace nrad
