// Scene helpers: geometry queries, bounds and automatic camera framing.
#include "baker/scene/scene.h"

#include <cmath>

namespace nrad {

float TriangleMesh::triangleArea(size_t t) const {
    const glm::uvec3& tri = triangles[t];
    return 0.5f * glm::length(glm::cross(positions[tri.y] - positions[tri.x], positions[tri.z] - positions[tri.x]));
}

glm::vec3 TriangleMesh::geometricNormal(size_t t) const {
    const glm::uvec3& tri = triangles[t];
    return glm::normalize(glm::cross(positions[tri.y] - positions[tri.x], positions[tri.z] - positions[tri.x]));
}

void Scene::updateBounds() {
    bounds = Bounds3{};
    for (const glm::vec3& p : mesh.positions) bounds.extend(p);
    for (const PunctualLight& l : lights)
        if (l.type != PunctualLight::Type::Directional) bounds.extend(l.position);
}

size_t Scene::emissiveTriangleCount() const {
    size_t n = 0;
    for (uint32_t m : mesh.materialIds) n += materials[m].emissive() ? 1 : 0;
    return n;
}

Camera frameBounds(const Bounds3& bounds, float yfov) {
    Camera camera;
    camera.name = "auto-framing";
    camera.yfov = yfov;
    float radius = bounds.empty() ? 1.0f : std::max(bounds.radius(), 1e-30f);
    glm::vec3 center = bounds.empty() ? glm::vec3(0.0f) : bounds.center();
    // Distance at which the bounding sphere fits the vertical field of view, plus a small margin.
    float distance = 1.05f * radius / std::sin(0.5f * yfov);
    camera.position = center + glm::vec3(0.0f, 0.0f, distance);
    camera.worldFromCamera = glm::mat3(1.0f);
    return camera;
}

}  // namespace nrad
