// Surface interactions: barycentric interpolation, texture lookups, ray-origin offsets.
#include "baker/render/surface.h"

#include <algorithm>
#include <cmath>
#include <limits>

namespace nrad {

namespace {

// The shading normal perturbed by the material's tangent-space normal map (glTF: n = normalize(T x + B y + N z),
// x and y scaled by normalScale, B = w cross(N, T)). N is the interpolated vertex normal on the winding side;
// returns N unchanged where the triangle has no tangent frame.
glm::vec3 normalMapped(const Scene& scene, const Material& m, const glm::uvec3& tri, float b0, float b1, float b2,
                       const glm::vec3& N) {
    const TriangleMesh& mesh = scene.mesh;
    if (!m.normalTexture.valid() || mesh.tangents.empty()) return N;
    glm::vec4 t4 = b0 * mesh.tangents[tri.x] + b1 * mesh.tangents[tri.y] + b2 * mesh.tangents[tri.z];
    glm::vec3 T = glm::vec3(t4) - glm::dot(glm::vec3(t4), N) * N;  // Gram-Schmidt against the interpolated normal
    float len = glm::length(T);
    if (!(len > 1e-6f) || !std::isfinite(len)) return N;
    T /= len;
    const float w = mesh.tangents[tri.x].w < 0.0f ? -1.0f : 1.0f;
    glm::vec3 B = w * glm::cross(N, T);
    glm::vec4 c = lookup(scene, m.normalTexture, mesh, tri, b0, b1, b2);
    glm::vec3 t(2.0f * c.x - 1.0f, 2.0f * c.y - 1.0f, 2.0f * c.z - 1.0f);
    t.x *= m.normalScale;
    t.y *= m.normalScale;
    glm::vec3 n = t.x * T + t.y * B + t.z * N;
    float nl = glm::length(n);
    return nl > 1e-6f && std::isfinite(nl) ? n / nl : N;
}

// Whether a triangle's three vertex normals are one and the same unit vector (a flat-shaded triangle, as most of
// an architectural scene's are): then the interpolated shading normal is that vector exactly, whatever the
// barycentrics. Unit within 1e-6 in squared length (half an ulp of 1 is 6e-8; normalising leaves about 1e-7).
inline bool flatUnitNormal(const glm::vec3& n0, const glm::vec3& n1, const glm::vec3& n2) {
    return n0 == n1 && n0 == n2 && std::abs(glm::dot(n0, n0) - 1.0f) < 1e-6f;
}

}  // namespace

float SurfaceInteraction::spawnDistance(const glm::vec3& w) const {
    float c = std::abs(glm::dot(w, ng));
    return c > 0.0f ? std::max(margin, rayOffset(p)) / c : std::numeric_limits<float>::infinity();
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

void prefetchInteraction(const Scene& scene, const Hit& hit) {
    const TriangleMesh& mesh = scene.mesh;
    const Material& m = scene.materials[mesh.materialIds[hit.triangle]];
    const glm::uvec3& tri = mesh.triangles[hit.triangle];
    const float b1 = hit.u, b2 = hit.v, b0 = 1.0f - b1 - b2;
    for (const TextureRef* ref : {&m.baseColorTexture, &m.normalTexture, &m.metallicRoughnessTexture, &m.emissiveTexture,
                                  &m.transmissionTexture})
        if (ref->valid()) scene.textures[size_t(ref->texture)].prefetch(ref->apply(texCoord(mesh, tri, b0, b1, b2, ref->texCoord)));
}

void makeInteraction(const Scene& scene, const Hit& hit, const glm::vec3& direction, SurfaceInteraction& si) {
    const TriangleMesh& mesh = scene.mesh;
    const glm::uvec3& tri = mesh.triangles[hit.triangle];
    float b1 = hit.u, b2 = hit.v, b0 = 1.0f - b1 - b2;
    si.triangle = hit.triangle;
    si.p = b0 * mesh.positions[tri.x] + b1 * mesh.positions[tri.y] + b2 * mesh.positions[tri.z];
    si.wo = -direction;
    glm::vec3 ng = hit.margin >= 0.0f ? hit.ng : mesh.geometricNormal(hit.triangle);
    const glm::vec3 &n0 = mesh.normals[tri.x], &n1 = mesh.normals[tri.y], &n2 = mesh.normals[tri.z];
    glm::vec3 ns;
    if (flatUnitNormal(n0, n1, n2)) {
        ns = n0;  // what interpolating and normalising computes, without its rounding (and its square root)
    } else {
        ns = b0 * n0 + b1 * n1 + b2 * n2;
        float nsLen = glm::length(ns);
        ns = (nsLen > 1e-6f && std::isfinite(nsLen)) ? ns / nsLen : ng;
    }
    if (glm::dot(ns, ng) < 0.0f) ns = -ns;  // vertex normals on the winding side
    const Material& m = scene.materials[mesh.materialIds[hit.triangle]];
    ns = normalMapped(scene, m, tri, b0, b1, b2, ns);
    si.frontFace = glm::dot(ng, si.wo) >= 0.0f;
    if (!si.frontFace) {
        ng = -ng;
        ns = -ns;
    }
    if (glm::dot(ns, si.wo) <= 0.0f) ns = ng;  // shading normal facing away from the viewer: use the true one
    si.ng = ng;
    si.ns = ns;

    si.material = &m;
    si.bsdf.baseColor = m.baseColor;
    si.bsdf.metallic = m.metallic;
    si.bsdf.roughness = m.roughness;
    si.bsdf.specular = m.specular;
    si.bsdf.specularColor = m.specularColor;
    si.bsdf.ior = m.ior;
    if (m.baseColorTexture.valid()) si.bsdf.baseColor *= glm::vec3(lookup(scene, m.baseColorTexture, mesh, tri, b0, b1, b2));
    if (!mesh.colors.empty()) si.bsdf.baseColor *= glm::vec3(vertexColor(mesh, tri, b0, b1, b2));
    if (m.metallicRoughnessTexture.valid()) {
        glm::vec4 mr = lookup(scene, m.metallicRoughnessTexture, mesh, tri, b0, b1, b2);
        si.bsdf.roughness *= mr.y;
        si.bsdf.metallic *= mr.z;
    }
    si.bsdf.transmission = m.transmission;
    if (m.transmission > 0.0f && m.transmissionTexture.valid())
        si.bsdf.transmission *= lookup(scene, m.transmissionTexture, mesh, tri, b0, b1, b2).x;
    si.bsdf.transmission = std::clamp(si.bsdf.transmission, 0.0f, 1.0f);
    si.bsdf.baseColor = glm::clamp(si.bsdf.baseColor, 0.0f, 1.0f);
    si.bsdf.metallic = std::clamp(si.bsdf.metallic, 0.0f, 1.0f);
    si.bsdf.roughness = std::clamp(si.bsdf.roughness, 0.0f, 1.0f);
    si.emission = emittedRadiance(scene, m, hit.triangle, hit.u, hit.v, si.frontFace);
    si.margin = hit.margin >= 0.0f ? hit.margin : triangleMargin(mesh, hit.triangle);
}

}  // namespace nrad
