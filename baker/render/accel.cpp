// Embree 3 scene for the flattened triangle mesh.
#include "baker/render/accel.h"

#include <algorithm>
#include <cstring>
#include <stdexcept>
#include <string>

#include <embree3/rtcore.h>

#include "baker/render/surface.h"

namespace nrad {

struct Accel::Impl {
    RTCDevice device = nullptr;
    RTCScene scene = nullptr;
    std::vector<glm::vec4> faces;  // per triangle: geometric normal, triangleMargin (Hit::ng, Hit::margin)
    ~Impl() {
        if (scene) rtcReleaseScene(scene);
        if (device) rtcReleaseDevice(device);
    }
};

namespace {

void errorCallback(void*, RTCError code, const char* message) {
    (void)code;
    (void)message;  // errors are checked with rtcGetDeviceError where they matter
}

inline void initRay(RTCRay& ray, const glm::vec3& o, const glm::vec3& d, float tnear, float tfar) {
    ray.org_x = o.x;
    ray.org_y = o.y;
    ray.org_z = o.z;
    ray.dir_x = d.x;
    ray.dir_y = d.y;
    ray.dir_z = d.z;
    ray.tnear = tnear;
    ray.tfar = tfar;
    ray.time = 0.0f;
    ray.mask = 0xFFFFFFFFu;  // Debian's Embree is built with ray masks: a zero mask misses everything
    ray.id = 0;
    ray.flags = 0;
}

// Coverage of alpha-tested and blended materials (both filter kinds; N = 1 for the queries we issue, but
// every lane is handled).
void coverageFilter(const RTCFilterFunctionNArguments* args) {
    const auto* scene = static_cast<const Scene*>(args->geometryUserPtr);
    for (unsigned i = 0; i < args->N; ++i) {
        if (args->valid[i] != -1) continue;
        const unsigned prim = RTCHitN_primID(args->hit, args->N, i);
        const float u = RTCHitN_u(args->hit, args->N, i), v = RTCHitN_v(args->hit, args->N, i);
        const float a = surfaceOpacity(*scene, prim, u, v);
        if (a >= 1.0f) continue;
        if (!(a > 0.0f)) {
            args->valid[i] = 0;
            continue;
        }
        // Stochastic coverage: a hash of the ray (origin, direction) and the triangle, uniform in [0, 1).
        float f[6] = {RTCRayN_org_x(args->ray, args->N, i), RTCRayN_org_y(args->ray, args->N, i),
                      RTCRayN_org_z(args->ray, args->N, i), RTCRayN_dir_x(args->ray, args->N, i),
                      RTCRayN_dir_y(args->ray, args->N, i), RTCRayN_dir_z(args->ray, args->N, i)};
        uint64_t h = 0xcbf29ce484222325ull ^ prim;
        for (float x : f) {
            uint32_t b;
            std::memcpy(&b, &x, 4);
            h = (h ^ b) * 0x100000001b3ull;
            h ^= h >> 29;
        }
        h *= 0xbf58476d1ce4e5b9ull;
        h ^= h >> 32;
        if (float(uint32_t(h) >> 8) * 0x1p-24f >= a) args->valid[i] = 0;
    }
}

bool needsCoverage(const Scene& scene) {
    for (const Material& m : scene.materials)
        if (m.alphaMode != Material::AlphaMode::Opaque) return true;
    return false;
}

}  // namespace

Accel::Accel(const TriangleMesh& mesh) : impl_(std::make_unique<Impl>()) { build(mesh, nullptr); }

Accel::Accel(const Scene& scene) : impl_(std::make_unique<Impl>()) {
    build(scene.mesh, needsCoverage(scene) ? &scene : nullptr);
}

void Accel::build(const TriangleMesh& mesh, const Scene* coverage) {
    impl_->faces.resize(mesh.triangles.size());
    for (uint32_t t = 0; t < uint32_t(mesh.triangles.size()); ++t)
        impl_->faces[t] = glm::vec4(mesh.geometricNormal(t), triangleMargin(mesh, t));
    impl_->device = rtcNewDevice(nullptr);
    if (!impl_->device) throw std::runtime_error("Embree: cannot create device (error " + std::to_string(int(rtcGetDeviceError(nullptr))) + ")");
    rtcSetDeviceErrorFunction(impl_->device, errorCallback, nullptr);
    impl_->scene = rtcNewScene(impl_->device);
    rtcSetSceneFlags(impl_->scene, RTC_SCENE_FLAG_ROBUST);
    rtcSetSceneBuildQuality(impl_->scene, RTC_BUILD_QUALITY_HIGH);
    if (!mesh.triangles.empty()) {
        RTCGeometry geom = rtcNewGeometry(impl_->device, RTC_GEOMETRY_TYPE_TRIANGLE);
        // Embree reads vertex buffers 16 bytes at a time: allocate one padding vertex at the end.
        auto* vertices = static_cast<float*>(rtcSetNewGeometryBuffer(
            geom, RTC_BUFFER_TYPE_VERTEX, 0, RTC_FORMAT_FLOAT3, 3 * sizeof(float), mesh.positions.size() + 1));
        auto* indices = static_cast<uint32_t*>(rtcSetNewGeometryBuffer(
            geom, RTC_BUFFER_TYPE_INDEX, 0, RTC_FORMAT_UINT3, 3 * sizeof(uint32_t), mesh.triangles.size()));
        if (!vertices || !indices) throw std::runtime_error("Embree: cannot allocate geometry buffers");
        for (size_t i = 0; i < mesh.positions.size(); ++i) {
            vertices[3 * i + 0] = mesh.positions[i].x;
            vertices[3 * i + 1] = mesh.positions[i].y;
            vertices[3 * i + 2] = mesh.positions[i].z;
        }
        vertices[3 * mesh.positions.size() + 0] = vertices[3 * mesh.positions.size() + 1] = vertices[3 * mesh.positions.size() + 2] = 0.0f;
        for (size_t t = 0; t < mesh.triangles.size(); ++t) {
            indices[3 * t + 0] = mesh.triangles[t].x;
            indices[3 * t + 1] = mesh.triangles[t].y;
            indices[3 * t + 2] = mesh.triangles[t].z;
        }
        if (coverage) {
            rtcSetGeometryUserData(geom, const_cast<Scene*>(coverage));
            rtcSetGeometryIntersectFilterFunction(geom, coverageFilter);
            rtcSetGeometryOccludedFilterFunction(geom, coverageFilter);
        }
        rtcCommitGeometry(geom);
        rtcAttachGeometryByID(impl_->scene, geom, 0);
        rtcReleaseGeometry(geom);
    }
    rtcCommitScene(impl_->scene);
    RTCError err = rtcGetDeviceError(impl_->device);
    if (err != RTC_ERROR_NONE) throw std::runtime_error("Embree: scene build failed (error " + std::to_string(int(err)) + ")");
}

Accel::~Accel() = default;

namespace {
// A closest-hit query with no hit yet.
void initRayHit(RTCRayHit& rh, const glm::vec3& origin, const glm::vec3& direction, float tnear, float tfar) {
    initRay(rh.ray, origin, direction, tnear, tfar);
    rh.hit.geomID = RTC_INVALID_GEOMETRY_ID;
    rh.hit.primID = RTC_INVALID_GEOMETRY_ID;
    rh.hit.instID[0] = RTC_INVALID_GEOMETRY_ID;
}

// The Hit of an answered closest-hit query, with the triangle's normal and margin from `faces`.
Hit hitOf(const RTCRayHit& rh, const std::vector<glm::vec4>& faces) {
    Hit hit;
    if (rh.hit.geomID == RTC_INVALID_GEOMETRY_ID) return hit;
    hit.t = rh.ray.tfar;
    hit.triangle = rh.hit.primID;
    hit.u = rh.hit.u;
    hit.v = rh.hit.v;
    const glm::vec4& face = faces[hit.triangle];
    hit.ng = glm::vec3(face);
    hit.margin = face.w;
    return hit;
}
}  // namespace

Hit Accel::intersect(const glm::vec3& origin, const glm::vec3& direction, float tnear, float tfar) const {
    RTCIntersectContext context;
    rtcInitIntersectContext(&context);
    RTCRayHit rh;
    initRayHit(rh, origin, direction, tnear, tfar);
    rtcIntersect1(impl_->scene, &context, &rh);
    return hitOf(rh, impl_->faces);
}

bool Accel::occluded(const glm::vec3& origin, const glm::vec3& direction, float tnear, float tfar) const {
    RTCIntersectContext context;
    rtcInitIntersectContext(&context);
    RTCRay ray;
    initRay(ray, origin, direction, tnear, tfar);
    rtcOccluded1(impl_->scene, &context, &ray);
    return ray.tfar < 0.0f;  // Embree marks an occluded ray with tfar = -inf
}

namespace {
// Embree's streams are processed in chunks of this many rays (the stream's own packets are 16 wide or less).
constexpr size_t kStreamChunk = 64;
}  // namespace

void Accel::intersect(const RayQuery* rays, size_t count, Hit* hits, bool coherent) const {
    RTCIntersectContext context;
    rtcInitIntersectContext(&context);  // RTC_INTERSECT_CONTEXT_FLAG_INCOHERENT: the single-ray kernels' results
    if (coherent) context.flags = RTC_INTERSECT_CONTEXT_FLAG_COHERENT;
    RTCRayHit chunk[kStreamChunk];
    for (size_t start = 0; start < count; start += kStreamChunk) {
        const size_t n = std::min(kStreamChunk, count - start);
        for (size_t i = 0; i < n; ++i) {
            const RayQuery& q = rays[start + i];
            initRayHit(chunk[i], q.origin, q.direction, q.tnear, q.tfar);
        }
        rtcIntersect1M(impl_->scene, &context, chunk, unsigned(n), sizeof(RTCRayHit));
        for (size_t i = 0; i < n; ++i) hits[start + i] = hitOf(chunk[i], impl_->faces);
    }
}

void Accel::occluded(const RayQuery* rays, size_t count, uint8_t* blocked) const {
    RTCIntersectContext context;
    rtcInitIntersectContext(&context);
    RTCRay chunk[kStreamChunk];
    for (size_t start = 0; start < count; start += kStreamChunk) {
        const size_t n = std::min(kStreamChunk, count - start);
        for (size_t i = 0; i < n; ++i) {
            const RayQuery& q = rays[start + i];
            initRay(chunk[i], q.origin, q.direction, q.tnear, q.tfar);
        }
        rtcOccluded1M(impl_->scene, &context, chunk, unsigned(n), sizeof(RTCRay));
        for (size_t i = 0; i < n; ++i) blocked[start + i] = chunk[i].tfar < 0.0f;
    }
}

size_t Accel::traceRaw(const RecordedRay* rays, size_t count) const {
    RTCIntersectContext context;
    rtcInitIntersectContext(&context);
    size_t hits = 0;
    for (size_t i = 0; i < count; ++i) {
        const RecordedRay& r = rays[i];
        if (r.shadow) {
            RTCRay ray;
            initRay(ray, r.origin, r.direction, r.tnear, r.tfar);
            rtcOccluded1(impl_->scene, &context, &ray);
            hits += ray.tfar < 0.0f;
        } else {
            RTCRayHit rh;
            initRay(rh.ray, r.origin, r.direction, r.tnear, r.tfar);
            rh.hit.geomID = RTC_INVALID_GEOMETRY_ID;
            rh.hit.instID[0] = RTC_INVALID_GEOMETRY_ID;
            rtcIntersect1(impl_->scene, &context, &rh);
            hits += rh.hit.geomID != RTC_INVALID_GEOMETRY_ID;
        }
    }
    return hits;
}

}  // namespace nrad
