// Pinhole and orthographic primary rays.
#include "baker/render/camera.h"

#include <algorithm>
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

namespace {

// The perspective directions of CameraRays::generate (x, y -> unit direction) for up to 64 points, as SoA.
// x86-64: clones for AVX2 and AVX-512, chosen at load time; no fused multiply-adds anywhere in this file
// (-ffp-contract=off), so every clone rounds as the one-ray generate() does.
#if defined(__x86_64__) && defined(__GNUC__) && !defined(__clang__) && !defined(NRAD_NO_TARGET_CLONES)
__attribute__((target_clones("avx512f", "avx2", "default")))
#endif
void perspectiveDirections(const glm::mat3& m, float w, float h, float hw, float hh, const float* __restrict x,
                           const float* __restrict y, size_t n, float* __restrict dx, float* __restrict dy,
                           float* __restrict dz) {
    const float m00 = m[0][0], m01 = m[0][1], m02 = m[0][2], m10 = m[1][0], m11 = m[1][1], m12 = m[1][2];
    const float m20 = m[2][0], m21 = m[2][1], m22 = m[2][2];
    for (size_t k = 0; k < n; ++k) {
        const float sx = (2.0f * x[k] / w - 1.0f) * hw;
        const float sy = (1.0f - 2.0f * y[k] / h) * hh;
        // m * (sx, sy, -1), then glm::normalize: v * (1 / sqrt(dot(v, v)))
        const float vx = m00 * sx + m10 * sy + m20 * -1.0f;
        const float vy = m01 * sx + m11 * sy + m21 * -1.0f;
        const float vz = m02 * sx + m12 * sy + m22 * -1.0f;
        const float inv = 1.0f / std::sqrt(vx * vx + vy * vy + vz * vz);
        dx[k] = vx * inv, dy[k] = vy * inv, dz[k] = vz * inv;
    }
}

}  // namespace

void CameraRays::generate(const float* x, const float* y, size_t n, RayQuery* out) const {
    if (camera_.type != Camera::Type::Perspective) {
        for (size_t k = 0; k < n; ++k) generate(x[k], y[k], out[k].origin, out[k].direction);
        return;
    }
    constexpr size_t kChunk = 64;
    float dx[kChunk], dy[kChunk], dz[kChunk];
    for (size_t first = 0; first < n; first += kChunk) {
        const size_t c = std::min(kChunk, n - first);
        perspectiveDirections(camera_.worldFromCamera, float(width_), float(height_), halfWidth_, halfHeight_, x + first,
                              y + first, c, dx, dy, dz);
        for (size_t k = 0; k < c; ++k) {
            out[first + k].origin = camera_.position;
            out[first + k].direction = glm::vec3(dx[k], dy[k], dz[k]);
        }
    }
}

}  // namespace nrad
