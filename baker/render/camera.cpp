// Pinhole and orthographic primary rays.
#include "baker/render/camera.h"

#include <cmath>

namespace nrad {

CameraRays::CameraRays(const Camera& camera, int width, int height) : camera_(camera), width_(width), height_(height) {
    float aspect = float(width) / float(height);
    if (camera.type == Camera::Type::Perspective) {
        halfHeight_ = std::tan(0.5f * camera.yfov);
        halfWidth_ = halfHeight_ * aspect;
    } else {
        halfHeight_ = camera.ymag;
        halfWidth_ = camera.ymag * aspect;
    }
}

void CameraRays::generate(float x, float y, glm::vec3& origin, glm::vec3& direction) const {
    float sx = (2.0f * x / float(width_) - 1.0f) * halfWidth_;
    float sy = (1.0f - 2.0f * y / float(height_)) * halfHeight_;
    const glm::mat3& m = camera_.worldFromCamera;
    if (camera_.type == Camera::Type::Perspective) {
        origin = camera_.position;
        direction = glm::normalize(m * glm::vec3(sx, sy, -1.0f));
    } else {
        origin = camera_.position + m[0] * sx + m[1] * sy;
        direction = -m[2];
    }
}

}  // namespace nrad
