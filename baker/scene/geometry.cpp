// Geometry the renderer and the lights share.
#include "baker/scene/geometry.h"

#include <algorithm>
#include <cmath>

namespace nrad {

Frame Frame::fromNormal(const glm::vec3& n) {
    // Duff et al. 2017, "Building an Orthonormal Basis, Revisited".
    float sign = std::copysign(1.0f, n.z);
    float a = -1.0f / (sign + n.z);
    float b = n.x * n.y * a;
    return {glm::vec3(1.0f + sign * n.x * n.x * a, sign * b, -sign * n.x), glm::vec3(b, sign + n.y * n.y * a, -n.y), n};
}

float rayOffset(const glm::vec3& p) {
    float m = std::max(std::abs(p.x), std::max(std::abs(p.y), std::abs(p.z)));
    // A few hundred float ulps of the largest coordinate, with a floor for points near the origin.
    return std::max(m * 4e-6f, 1e-30f);
}

float triangleMargin(const TriangleMesh& mesh, uint32_t t) {
    const glm::uvec3& tri = mesh.triangles[t];
    glm::vec3 m = glm::max(glm::abs(mesh.positions[tri.x]), glm::max(glm::abs(mesh.positions[tri.y]), glm::abs(mesh.positions[tri.z])));
    return rayOffset(m);
}

}  // namespace nrad
