// Camera rays: primary ray generation for a scene Camera and an image size.
#pragma once

#include <cstddef>

#include <glm/glm.hpp>

#include "baker/render/accel.h"
#include "baker/scene/scene.h"

namespace nrad {

class CameraRays {
public:
    CameraRays(const Camera& camera, int width, int height);
    // (x, y): continuous raster position, (0, 0) the top-left corner of the image.
    void generate(float x, float y, glm::vec3& origin, glm::vec3& direction) const;
    // generate() at (x[k], y[k]) into out[k].origin and out[k].direction for k < n (their interval untouched):
    // the same bits, in loops the compiler vectorises (a batch's camera rays).
    void generate(const float* x, const float* y, size_t n, RayQuery* out) const;

private:
    Camera camera_;
    int width_, height_;
    float halfHeight_, halfWidth_;  // of the image plane at distance 1 (perspective) or in world units (ortho)
};

}  // namespace nrad
