// Analytic test scenes.
#include "support/test_scenes.h"

#include <cmath>

#include "baker/render/accel.h"
#include "baker/lights/light_sampler.h"
#include "baker/render/path_tracer.h"
#include "baker/util/threads.h"

namespace nrad::test {

Scene makeSphereFurnace(const Material& material, float radius, int segments, bool smoothNormals) {
    Scene scene;
    scene.sourcePath = "<sphere furnace>";
    Material m = material;
    m.doubleSided = true;
    scene.materials.push_back(m);
    const int rings = segments / 2;
    const float pi = 3.14159265358979323846f;
    TriangleMesh& mesh = scene.mesh;
    // Poles are single vertices so the sphere is watertight.
    auto addVertex = [&](const glm::vec3& n) {
        mesh.positions.push_back(radius * n);
        mesh.normals.push_back(n);
        mesh.uv0.emplace_back(0.0f);
        mesh.uv1.emplace_back(0.0f);
        return uint32_t(mesh.positions.size() - 1);
    };
    uint32_t north = addVertex({0, 1, 0});
    std::vector<uint32_t> ringStart;
    for (int r = 1; r < rings; ++r) {
        float theta = pi * float(r) / float(rings);
        ringStart.push_back(uint32_t(mesh.positions.size()));
        for (int s = 0; s < segments; ++s) {
            float phi = 2.0f * pi * float(s) / float(segments);
            addVertex({std::sin(theta) * std::cos(phi), std::cos(theta), std::sin(theta) * std::sin(phi)});
        }
    }
    uint32_t south = addVertex({0, -1, 0});
    auto idx = [&](int ring, int s) { return ringStart[size_t(ring)] + uint32_t(s % segments); };
    for (int s = 0; s < segments; ++s) mesh.triangles.emplace_back(north, idx(0, s + 1), idx(0, s));
    for (int r = 0; r + 1 < rings - 1; ++r)
        for (int s = 0; s < segments; ++s) {
            mesh.triangles.emplace_back(idx(r, s), idx(r, s + 1), idx(r + 1, s));
            mesh.triangles.emplace_back(idx(r, s + 1), idx(r + 1, s + 1), idx(r + 1, s));
        }
    for (int s = 0; s < segments; ++s) mesh.triangles.emplace_back(south, idx(rings - 2, s), idx(rings - 2, s + 1));
    if (!smoothNormals) {
        // Unshared vertices with the facet normal; positions are bit-identical copies, so the surface
        // stays watertight for Embree.
        TriangleMesh flat;
        for (const glm::uvec3& t : mesh.triangles) {
            glm::vec3 n = glm::normalize(glm::cross(mesh.positions[t.y] - mesh.positions[t.x], mesh.positions[t.z] - mesh.positions[t.x]));
            uint32_t first = uint32_t(flat.positions.size());
            for (uint32_t v : {t.x, t.y, t.z}) {
                flat.positions.push_back(mesh.positions[v]);
                flat.normals.push_back(n);
                flat.uv0.emplace_back(0.0f);
                flat.uv1.emplace_back(0.0f);
            }
            flat.triangles.emplace_back(first, first + 1, first + 2);
        }
        mesh = std::move(flat);
    }
    mesh.materialIds.assign(mesh.triangles.size(), 0);
    Camera camera;
    camera.yfov = pi / 2.0f;
    scene.cameras.push_back(camera);
    scene.updateBounds();
    return scene;
}

Scene makeLitPlane(float albedo, float halfSize) {
    Scene scene;
    scene.sourcePath = "<lit plane>";
    Material m;
    m.baseColor = glm::vec3(albedo);
    m.metallic = 0.0f;
    m.specular = 0.0f;
    scene.materials.push_back(m);
    TriangleMesh& mesh = scene.mesh;
    for (glm::vec2 c : {glm::vec2(-1, -1), glm::vec2(1, -1), glm::vec2(1, 1), glm::vec2(-1, 1)}) {
        mesh.positions.emplace_back(halfSize * c.x, halfSize * c.y, 0.0f);
        mesh.normals.emplace_back(0, 0, 1);
        mesh.uv0.emplace_back(0.0f);
        mesh.uv1.emplace_back(0.0f);
    }
    mesh.triangles = {{0, 1, 2}, {0, 2, 3}};
    mesh.materialIds = {0, 0};
    Camera camera;
    camera.type = Camera::Type::Orthographic;
    camera.position = glm::vec3(0, 0, 5);
    camera.xmag = camera.ymag = 1.0f;
    scene.cameras.push_back(camera);
    scene.updateBounds();
    return scene;
}

Image renderPathTraced(const Scene& scene, int size, int spp, int maxDepth, uint32_t seed, int tileSize) {
    Accel accel(scene);
    LightSampler lights(scene);
    PathTracer tracer(scene, accel, lights);
    RenderSettings s;
    s.width = s.height = size;
    s.spp = spp;
    s.maxDepth = maxDepth;
    s.seed = seed;
    s.tileSize = tileSize;
    return tracer.render(scene.cameras[0], s);
}

std::vector<uint8_t> bakeBytes(const Scene& scene, const BakeSettings& settings, int threads) {
    ThreadScope scope(threads);
    return format::encode(bakeScene(scene, settings).asset);
}

Scene makeScaffold() {
    Scene scene;
    scene.sourcePath = "<scaffold>";
    Material m;
    m.baseColor = glm::vec3(0.0f);
    m.metallic = 0.0f;
    m.specular = 0.0f;
    m.doubleSided = true;
    scene.materials.push_back(m);
    TriangleMesh& mesh = scene.mesh;
    for (int c = 0; c < 8; ++c) {
        const glm::vec3 corner(c & 1 ? 1.0f : -1.0f, c & 2 ? 1.0f : -1.0f, c & 4 ? 1.0f : -1.0f);
        const glm::vec3 in = -0.01f * corner;
        const uint32_t at = uint32_t(mesh.positions.size());
        for (const glm::vec3& p : {corner, corner + glm::vec3(in.x, 0, 0), corner + glm::vec3(0, in.y, 0)}) {
            mesh.positions.push_back(p);
            mesh.normals.emplace_back(0, 0, corner.z);
            mesh.uv0.emplace_back(0.0f);
            mesh.uv1.emplace_back(0.0f);
        }
        mesh.triangles.push_back({at, at + 1, at + 2});
        mesh.materialIds.push_back(0);
    }
    scene.updateBounds();
    return scene;
}

}  // namespace nrad::test
