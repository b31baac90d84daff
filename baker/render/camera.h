// Camera rays: primary ray generation for a scene Camera and an image size.
#pragma once

#include <cstddef>

#include <glm/glm.hpp>

#include "baker/render/accel.h"
#include "baker/render/sampler.h"
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

// Sample `index` of pixel (x, y): its sampler (stream pixelStream(x, y, seed)) and the camera ray through the
// sampler's first 2D point, a position within the pixel. Returns the sampler, ready for the path's next
// dimensions. Every renderer's camera paths start here, so their images agree bit for bit; the path
// tracer's batches compute the same bits in lanes (PathTracer::render, tested against the plain tiles).
inline Sampler cameraSample(const CameraRays& rays, int x, int y, uint32_t seed, uint32_t index, glm::vec3& origin,
                            glm::vec3& direction) {
    Sampler sampler(pixelStream(uint32_t(x), uint32_t(y), seed), index);
    const glm::vec2 jitter = sampler.get2D();
    rays.generate(float(x) + jitter.x, float(y) + jitter.y, origin, direction);
    return sampler;
}

}  // namespace nrad
