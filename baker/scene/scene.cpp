// Scene helpers: geometry queries, bounds and automatic camera framing.
#include "baker/scene/scene.h"

#include <algorithm>
#include <cmath>

#include "baker/scene/gltf_loader.h"

namespace nrad {

glm::vec2 TextureRef::apply(glm::vec2 uv) const {
    if (!transformed()) return uv;
    glm::vec2 s = scale * uv;
    float c = std::cos(rotation), r = std::sin(rotation);
    return offset + glm::vec2(c * s.x + r * s.y, -r * s.x + c * s.y);
}

float TriangleMesh::triangleArea(size_t t) const {
    const glm::uvec3& tri = triangles[t];
    return 0.5f * glm::length(glm::cross(positions[tri.y] - positions[tri.x], positions[tri.z] - positions[tri.x]));
}

glm::vec3 TriangleMesh::geometricNormal(size_t t) const {
    const glm::uvec3& tri = triangles[t];
    return glm::normalize(glm::cross(positions[tri.y] - positions[tri.x], positions[tri.z] - positions[tri.x]));
}

int Scene::insertedObject(size_t t) const {
    auto it = std::upper_bound(insertedObjects.begin(), insertedObjects.end(), t);
    return int(it - insertedObjects.begin()) - 1;
}

void insertObject(Scene& scene, const Scene& object, const glm::vec3& offset, const std::string& name) {
    if (object.mesh.triangleCount() == 0) throw SceneError(name + ": the object has no triangles to insert");
    TriangleMesh& m = scene.mesh;
    const TriangleMesh& o = object.mesh;
    const size_t vertices = m.positions.size(), added = o.positions.size();
    if (vertices + added >= size_t(UINT32_MAX)) throw SceneError(name + ": the scene with the object would have more than 2^32 - 1 vertices");
    const uint32_t materialBase = uint32_t(scene.materials.size());
    const int textureBase = int(scene.textures.size());
    scene.insertedObjects.push_back(m.triangleCount());
    scene.insertedNames.push_back(name);
    for (const glm::vec3& p : o.positions) m.positions.push_back(p + offset);
    m.normals.insert(m.normals.end(), o.normals.begin(), o.normals.end());
    m.uv0.insert(m.uv0.end(), o.uv0.begin(), o.uv0.end());
    m.uv1.insert(m.uv1.end(), o.uv1.begin(), o.uv1.end());
    // Optional attributes: present in either, then one per vertex of both (the defaults where absent).
    auto merge = [&](std::vector<glm::vec4>& to, const std::vector<glm::vec4>& from, const glm::vec4& none) {
        if (to.empty() && from.empty()) return;
        to.resize(vertices, none);
        if (from.empty()) to.resize(vertices + added, none);
        else to.insert(to.end(), from.begin(), from.end());
    };
    merge(m.colors, o.colors, glm::vec4(1.0f));
    merge(m.tangents, o.tangents, glm::vec4(0.0f, 0.0f, 0.0f, 1.0f));
    for (const glm::uvec3& t : o.triangles) m.triangles.push_back(t + glm::uvec3(uint32_t(vertices)));
    for (uint32_t id : o.materialIds) m.materialIds.push_back(id + materialBase);
    for (Material mat : object.materials) {
        for (TextureRef* ref : {&mat.baseColorTexture, &mat.metallicRoughnessTexture, &mat.emissiveTexture,
                                &mat.transmissionTexture, &mat.normalTexture})
            if (ref->valid()) ref->texture += textureBase;
        scene.materials.push_back(std::move(mat));
    }
    scene.textures.insert(scene.textures.end(), object.textures.begin(), object.textures.end());
    scene.updateBounds();
}

Scene withoutInsertedObjects(const Scene& scene) {
    Scene bare = scene;
    if (scene.insertedObjects.empty()) return bare;
    const size_t keep = scene.insertedObjects.front();
    uint32_t firstVertex = UINT32_MAX;  // the inserted vertices follow all of the scene's own
    for (size_t t = keep; t < scene.mesh.triangleCount(); ++t)
        for (int k = 0; k < 3; ++k) firstVertex = std::min(firstVertex, scene.mesh.triangles[t][k]);
    TriangleMesh& m = bare.mesh;
    m.triangles.resize(keep);
    m.materialIds.resize(keep);
    for (auto* v : {&m.positions, &m.normals})
        if (v->size() > firstVertex) v->resize(firstVertex);
    for (auto* v : {&m.uv0, &m.uv1})
        if (v->size() > firstVertex) v->resize(firstVertex);
    for (auto* v : {&m.colors, &m.tangents})
        if (v->size() > firstVertex) v->resize(firstVertex);
    bare.insertedObjects.clear();
    bare.insertedNames.clear();
    bare.updateBounds();
    return bare;
}

void Scene::updateBounds() {
    bounds = Bounds3{};
    for (const glm::vec3& p : mesh.positions) bounds.extend(p);
    for (const PunctualLight& l : lights)
        if (l.type != PunctualLight::Type::Directional) bounds.extend(l.position);
}

glm::vec3 Scene::triangleEmission(size_t t) const {
    const Material& m = materials[mesh.materialIds[t]];
    if (!m.emissive()) return glm::vec3(0.0f);
    if (!m.emissiveTexture.valid()) return m.emission;
    const Texture& tex = textures[size_t(m.emissiveTexture.texture)];
    const std::vector<glm::vec2>& uv = m.emissiveTexture.texCoord == 1 ? mesh.uv1 : mesh.uv0;
    const glm::uvec3& tri = mesh.triangles[t];
    const TextureRef& ref = m.emissiveTexture;
    const glm::vec2 a = ref.apply(uv[tri.x]), b = ref.apply(uv[tri.y]), c = ref.apply(uv[tri.z]);
    // Texels covered, and a lattice about as dense as them (a 99.9% black emissive texture must not make
    // every triangle a light, nor a small bright spot be missed by one lookup at the centroid).
    glm::vec2 e1 = (b - a) * glm::vec2(float(tex.width), float(tex.height));
    glm::vec2 e2 = (c - a) * glm::vec2(float(tex.width), float(tex.height));
    float texels = 0.5f * std::abs(e1.x * e2.y - e1.y * e2.x);
    int n = std::isfinite(texels) ? std::clamp(int(std::ceil(std::sqrt(texels))), 1, 16) : 16;
    // Centroids of the n^2 equal sub-triangles: (i + 1/3, j + 1/3) / n for i + j < n, (i + 2/3, j + 2/3) / n for
    // i + j < n - 1.
    glm::dvec3 sum(0.0);
    int count = 0;
    for (int i = 0; i < n; ++i)
        for (int j = 0; i + j < n; ++j)
            for (int k = 0; k < 2; ++k) {
                if (k == 1 && i + j >= n - 1) continue;
                float off = k == 0 ? 1.0f / 3.0f : 2.0f / 3.0f;
                float b1 = (float(i) + off) / float(n), b2 = (float(j) + off) / float(n);
                glm::vec2 p = (1.0f - b1 - b2) * a + b1 * b + b2 * c;
                sum += glm::dvec3(glm::vec3(tex.sample(p)));
                ++count;
            }
    return m.emission * glm::vec3(sum / double(count));
}

namespace {
bool emitsLight(const Scene& scene, size_t t) {
    if (!scene.materials[scene.mesh.materialIds[t]].emissive()) return false;  // no texture lattice to average
    glm::vec3 e = scene.triangleEmission(t);
    return (e.x > 0.0f || e.y > 0.0f || e.z > 0.0f) && scene.mesh.triangleArea(t) > 0.0f;
}
}  // namespace

size_t Scene::emissiveTriangleCount() const {
    size_t n = 0;
    for (size_t t = 0; t < mesh.triangleCount(); ++t) n += emitsLight(*this, t) ? 1 : 0;
    return n;
}

bool Scene::hasLight() const {
    if (environment.active()) return true;
    for (size_t t = 0; t < mesh.triangleCount(); ++t)
        if (emitsLight(*this, t)) return true;  // the first one settles it
    for (const PunctualLight& l : lights)
        if (l.intensity.x > 0.0f || l.intensity.y > 0.0f || l.intensity.z > 0.0f) return true;
    return false;
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
