// What a material gives at a point of a triangle.
#include "baker/scene/material_lookup.h"

#include <algorithm>

namespace nrad {

glm::vec3 emittedRadiance(const Scene& scene, const Material& m, uint32_t triangle, float u, float v, bool front) {
    if (!m.emissive() || (!front && !m.doubleSided)) return glm::vec3(0.0f);
    glm::vec3 e = m.emission;
    if (m.emissiveTexture.valid())
        e *= glm::vec3(lookup(scene, m.emissiveTexture, scene.mesh, scene.mesh.triangles[triangle], 1.0f - u - v, u, v));
    return e;
}

glm::vec3 emittedRadiance(const Scene& scene, uint32_t triangle, float u, float v, bool front) {
    return emittedRadiance(scene, scene.materials[scene.mesh.materialIds[triangle]], triangle, u, v, front);
}

float surfaceOpacity(const Scene& scene, uint32_t triangle, float u, float v) {
    const Material& m = scene.materials[scene.mesh.materialIds[triangle]];
    if (m.alphaMode == Material::AlphaMode::Opaque) return 1.0f;
    const glm::uvec3& tri = scene.mesh.triangles[triangle];
    float b0 = 1.0f - u - v;
    float a = m.alpha * vertexColor(scene.mesh, tri, b0, u, v).w;
    if (m.baseColorTexture.valid()) a *= lookup(scene, m.baseColorTexture, scene.mesh, tri, b0, u, v).w;
    a = std::clamp(a, 0.0f, 1.0f);
    if (m.alphaMode == Material::AlphaMode::Mask) return a >= m.alphaCutoff ? 1.0f : 0.0f;
    return a;
}

}  // namespace nrad
