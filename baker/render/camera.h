// Camera rays: primary ray generation for a scene Camera and an image size.
#pragma once

#include <glm/glm.hpp>

#include "baker/scene/scene.h"

namespace nrad {

class CameraRays {
public:
    CameraRays(const Camera& camera, int width, int height);
    // (x, y): continuous raster position, (0, 0) the top-left corner of the image.
    void generate(float x, float y, glm::vec3& origin, glm::vec3& direction) const;

private:
    Camera camera_;
    int width_, height_;
    float halfHeight_, halfWidth_;  // of the image plane at distance 1 (perspective) or in world units (ortho)
};

}  // namespace nrad
