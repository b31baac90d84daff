// Surface interactions: barycentric interpolation, texture lookups, ray-origin offsets.
#include "baker/render/surface.h"

#include <algorithm>
#include <cmath>
#include <limits>

namespace nrad {

namespace {

glm::vec2 texCoord(const TriangleMesh& mesh, const glm::uvec3& tri, float b0, float b1, float b2, int set) {
    const std::vector<glm::vec2>& uv = set == 1 ? mesh.uv1 : mesh.uv0;
    return b0 * uv[tri.x] + b1 * uv[tri.y] + b2 * uv[tri.z];
}

glm::vec4 lookup(const Scene& scene, const TextureRef& ref, const TriangleMesh& mesh, const glm::uvec3& tri, float b0,
                 float b1, float b2) {
    if (!ref.valid()) return glm::vec4(1.0f);
    return scene.textures[size_t(ref.texture)].sample(texCoord(mesh, tri, b0, b1, b2, ref.texCoord));
}

}  // namespace

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

float SurfaceInteraction::spawnDistance(const glm::vec3& w) const {
    float c = std::abs(glm::dot(w, ng));
    return c > 0.0f ? std::max(margin, rayOffset(p)) / c : std::numeric_limits<float>::infinity();
}

glm::vec3 emittedRadiance(const Scene& scene, uint32_t triangle, float u, float v, bool front) {
    const Material& m = scene.materials[scene.mesh.materialIds[triangle]];
    if (!m.emissive() || (!front && !m.doubleSided)) return glm::vec3(0.0f);
    glm::vec3 e = m.emission;
    if (m.emissiveTexture.valid())
        e *= glm::vec3(lookup(scene, m.emissiveTexture, scene.mesh, scene.mesh.triangles[triangle], 1.0f - u - v, u, v));
    return e;
}

eval::Surface shadingSurface(const SurfaceInteraction& si) {
    eval::Surface s;
    for (int c = 0; c < 3; ++c) {
        s.baseColor[c] = si.bsdf.baseColor[c];
        s.emission[c] = si.emission[c];
    }
    s.metallic = si.bsdf.metallic;
    s.roughness = si.bsdf.roughness;
    s.specular = si.bsdf.specular;
    return s;
}

SurfaceInteraction makeInteraction(const Scene& scene, const Hit& hit, const glm::vec3& direction) {
    const TriangleMesh& mesh = scene.mesh;
    const glm::uvec3& tri = mesh.triangles[hit.triangle];
    float b1 = hit.u, b2 = hit.v, b0 = 1.0f - b1 - b2;
    SurfaceInteraction si;
    si.triangle = hit.triangle;
    si.p = b0 * mesh.positions[tri.x] + b1 * mesh.positions[tri.y] + b2 * mesh.positions[tri.z];
    si.wo = -direction;
    glm::vec3 ng = mesh.geometricNormal(hit.triangle);
    glm::vec3 ns = b0 * mesh.normals[tri.x] + b1 * mesh.normals[tri.y] + b2 * mesh.normals[tri.z];
    float nsLen = glm::length(ns);
    ns = (nsLen > 1e-6f && std::isfinite(nsLen)) ? ns / nsLen : ng;
    if (glm::dot(ns, ng) < 0.0f) ns = -ns;  // vertex normals on the winding side
    si.frontFace = glm::dot(ng, si.wo) >= 0.0f;
    if (!si.frontFace) {
        ng = -ng;
        ns = -ns;
    }
    if (glm::dot(ns, si.wo) <= 0.0f) ns = ng;  // shading normal facing away from the viewer: use the true one
    si.ng = ng;
    si.ns = ns;

    const Material& m = scene.materials[mesh.materialIds[hit.triangle]];
    si.material = &m;
    si.bsdf.baseColor = m.baseColor;
    si.bsdf.metallic = m.metallic;
    si.bsdf.roughness = m.roughness;
    si.bsdf.specular = m.specular;
    si.bsdf.specularColor = m.specularColor;
    si.bsdf.ior = m.ior;
    if (m.baseColorTexture.valid()) si.bsdf.baseColor *= glm::vec3(lookup(scene, m.baseColorTexture, mesh, tri, b0, b1, b2));
    if (m.metallicRoughnessTexture.valid()) {
        glm::vec4 mr = lookup(scene, m.metallicRoughnessTexture, mesh, tri, b0, b1, b2);
        si.bsdf.roughness *= mr.y;
        si.bsdf.metallic *= mr.z;
    }
    si.bsdf.baseColor = glm::clamp(si.bsdf.baseColor, 0.0f, 1.0f);
    si.bsdf.metallic = std::clamp(si.bsdf.metallic, 0.0f, 1.0f);
    si.bsdf.roughness = std::clamp(si.bsdf.roughness, 0.0f, 1.0f);
    si.emission = emittedRadiance(scene, hit.triangle, hit.u, hit.v, si.frontFace);
    si.margin = triangleMargin(mesh, hit.triangle);
    return si;
}

}  // namespace nrad
