// Accel: ray queries against the scene's triangles. The only module that sees Embree; the rest of the
// code uses these project types.
#pragma once

#include <cstdint>
#include <limits>
#include <memory>
#include <vector>

#include <glm/glm.hpp>

#include "baker/scene/geometry.h"
#include "baker/scene/scene.h"

namespace nrad {

struct Hit {
    float t = std::numeric_limits<float>::infinity();
    uint32_t triangle = UINT32_MAX;
    float u = 0.0f, v = 0.0f;  // barycentrics of vertices 1 and 2
    // From Accel's table of the triangles, computed once: TriangleMesh::geometricNormal and triangleMargin
    // of the triangle hit (margin < 0: not given, as in a Hit made by hand; makeInteraction computes them).
    glm::vec3 ng{0.0f};
    float margin = -1.0f;
    bool valid() const { return triangle != UINT32_MAX; }
};

// One query of a batch: origin + t * direction for t in [tnear, tfar).
struct RayQuery {
    glm::vec3 origin{0.0f};
    glm::vec3 direction{0.0f};
    float tnear = 0.0f;
    float tfar = std::numeric_limits<float>::infinity();
};

// A ray as the path tracer issued it, for replaying the same distribution in benchmarks.
struct RecordedRay {
    glm::vec3 origin;
    glm::vec3 direction;
    float tnear;
    float tfar;
    bool shadow;
};

class Accel {
public:
    // Every triangle opaque.
    explicit Accel(const TriangleMesh& mesh);
    // The scene's triangles with their materials' coverage: an Embree filter drops hits where a MASK
    // material's alpha is below its cutoff (light passes through the holes) and, for BLEND, with probability
    // 1 - alpha (a hash of the ray and the triangle decides, so a query is deterministic). Scenes without
    // such materials get no filter. The scene must outlive the Accel.
    explicit Accel(const Scene& scene);
    ~Accel();
    Accel(const Accel&) = delete;
    Accel& operator=(const Accel&) = delete;

    // Closest hit along origin + t * direction for t in [tnear, tfar).
    Hit intersect(const glm::vec3& origin, const glm::vec3& direction, float tnear = 0.0f,
                  float tfar = std::numeric_limits<float>::infinity()) const;
    // True if anything blocks the segment [tnear, tfar).
    bool occluded(const glm::vec3& origin, const glm::vec3& direction, float tnear, float tfar) const;

    // Many queries at once, through Embree's ray streams (rtcIntersect1M / rtcOccluded1M, incoherent): the
    // same hits, bit for bit, as intersect() and occluded() one ray at a time (path_tracer_test), at less cost
    // per ray (docs/performance.md). blocked[i] is 1 where something blocks rays[i]. coherent: rays that start
    // together and point alike (camera rays) in Embree's packets, faster for them, but the packet kernels'
    // hits differ from the single-ray ones in the last bits now and then.
    void intersect(const RayQuery* rays, size_t count, Hit* hits, bool coherent = false) const;
    void occluded(const RayQuery* rays, size_t count, uint8_t* blocked) const;

    // Replays recorded rays through plain rtcIntersect1 / rtcOccluded1 and returns the number of hits:
    // the raw Embree throughput baseline the path tracer is measured against.
    size_t traceRaw(const RecordedRay* rays, size_t count) const;

private:
    void build(const TriangleMesh& mesh, const Scene* coverage);
    struct Impl;
    std::unique_ptr<Impl> impl_;
};

}  // namespace nrad
