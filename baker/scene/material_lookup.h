// What a material gives at a point of a triangle: texture coordinates, texel and vertex-colour lookups, the
// emitted radiance and the coverage. Below the renderer and the lights, which both read them.
#pragma once

#include <cstdint>

#include <glm/glm.hpp>

#include "baker/scene/scene.h"

namespace nrad {

// Texture coordinates of set `set` (0 or 1) at barycentrics (b0, b1, b2) of the triangle's vertices.
inline glm::vec2 texCoord(const TriangleMesh& mesh, const glm::uvec3& tri, float b0, float b1, float b2, int set) {
    const std::vector<glm::vec2>& uv = set == 1 ? mesh.uv1 : mesh.uv0;
    return b0 * uv[tri.x] + b1 * uv[tri.y] + b2 * uv[tri.z];
}

// The texel a texture reference gives there (1 where the reference names no texture).
inline glm::vec4 lookup(const Scene& scene, const TextureRef& ref, const TriangleMesh& mesh, const glm::uvec3& tri, float b0,
                        float b1, float b2) {
    if (!ref.valid()) return glm::vec4(1.0f);
    return scene.textures[size_t(ref.texture)].sample(ref.apply(texCoord(mesh, tri, b0, b1, b2, ref.texCoord)));
}

// COLOR_0 there (1 where the mesh has none).
inline glm::vec4 vertexColor(const TriangleMesh& mesh, const glm::uvec3& tri, float b0, float b1, float b2) {
    if (mesh.colors.empty()) return glm::vec4(1.0f);
    return b0 * mesh.colors[tri.x] + b1 * mesh.colors[tri.y] + b2 * mesh.colors[tri.z];
}

// Emitted radiance of a triangle at barycentrics (u, v), seen from a direction on the side `front`.
glm::vec3 emittedRadiance(const Scene& scene, uint32_t triangle, float u, float v, bool front);
// The same with the triangle's material already found.
glm::vec3 emittedRadiance(const Scene& scene, const Material& m, uint32_t triangle, float u, float v, bool front);

// Coverage of triangle `triangle` at barycentrics (u, v): 1 for opaque materials; for MASK 1 or 0 (alpha
// against the cutoff); for BLEND alpha itself, the probability that a ray stops there. Alpha is the
// base colour factor's times the base colour texture's times COLOR_0's.
float surfaceOpacity(const Scene& scene, uint32_t triangle, float u, float v);

}  // namespace nrad
