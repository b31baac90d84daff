// Direct light from polygonal Lambertian emitters against the closed form (issue 12). The irradiance at a
// point p with normal n from a polygon of constant radiance Le is Lambert's formula
//     E = Le / 2 * | sum over edges (v_i, v_i+1) of angle(v_i - p, v_i+1 - p) * n . unit(cross(v_i - p, v_i+1 - p)) |
// for the part of the polygon above p's tangent plane, so a Lambertian receiver of albedo a sends
// L = a / pi * E. nrad's radiance at --max-depth 2 (NEE + BSDF sampling with MIS) must agree with it within a
// few standard errors at every receiver that can see an emitter: near and far (10x the light's size and
// more), tilted, at grazing angles down to about one degree, behind a one-sided light (exactly 0), for quads
// and lone triangles, in every light selection mode (learned: trained at the receiver, then frozen), and with
// the whole scene scaled by 1e-3 and 1e4 or moved far from the origin.
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <memory>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "baker/render/accel.h"
#include "baker/lights/light_sampler.h"
#include "baker/lights/light_selection.h"
#include "baker/render/path_tracer.h"
#include "baker/render/sampler.h"
#include "baker/render/surface.h"

namespace nrad {
namespace {

constexpr double kPi = 3.14159265358979323846;
constexpr float kAlbedo = 0.5f;

using Polygon = std::vector<glm::dvec3>;

// The part of polygon `poly` where dot(x - p, n) >= 0 (Sutherland-Hodgman against one plane).
Polygon clipAbove(const Polygon& poly, const glm::dvec3& p, const glm::dvec3& n) {
    Polygon out;
    for (size_t i = 0; i < poly.size(); ++i) {
        const glm::dvec3 &a = poly[i], &b = poly[(i + 1) % poly.size()];
        double da = glm::dot(a - p, n), db = glm::dot(b - p, n);
        if (da >= 0.0) out.push_back(a);
        if ((da >= 0.0) != (db >= 0.0)) out.push_back(a + (b - a) * (da / (da - db)));
    }
    return out;
}

// Irradiance per unit radiance (E / Le) at p with unit normal n from a polygon; zero if none of it is above
// the tangent plane.
double lambertPolygon(const Polygon& poly, const glm::dvec3& p, const glm::dvec3& n) {
    Polygon c = clipAbove(poly, p, n);
    if (c.size() < 3) return 0.0;
    double sum = 0.0;
    for (size_t i = 0; i < c.size(); ++i) {
        glm::dvec3 a = glm::normalize(c[i] - p), b = glm::normalize(c[(i + 1) % c.size()] - p);
        glm::dvec3 g = glm::cross(a, b);
        double len = glm::length(g);
        if (!(len > 0.0)) continue;
        sum += std::atan2(len, glm::dot(a, b)) * glm::dot(n, g / len);
    }
    return 0.5 * std::abs(sum);
}

// One emitter of the test scenes, in the base frame (light plane y = 0, emitting side +y, sizes of 0.4).
struct Emitter {
    Polygon polygon;  // wound so that cross(v1 - v0, v2 - v0) points to +y
    bool doubleSided = false;
};

struct LightRig {
    std::string name;
    std::vector<Emitter> emitters;
};

std::vector<LightRig> lightRigs() {
    Polygon quad = {{-0.2, 0, 0.2}, {0.2, 0, 0.2}, {0.2, 0, -0.2}, {-0.2, 0, -0.2}};
    Polygon triangle = {{-0.2, 0, 0.15}, {0.2, 0, 0.15}, {0.0, 0, -0.25}};
    Polygon sideTriangle = {{0.3, 0, 0.2}, {0.6, 0, 0.2}, {0.45, 0, -0.2}};
    return {{"quad", {{quad, false}}},
            {"double-sided quad", {{quad, true}}},
            {"triangle", {{triangle, false}}},
            {"quad and triangle", {{quad, false}, {sideTriangle, false}}}};
}

// A similarity transform applied to the whole scene (receiver included).
struct Placement {
    std::string name;
    double scale = 1.0;
    glm::dvec3 offset{0.0};
    glm::dvec3 apply(const glm::dvec3& x) const { return x * scale + offset; }
};

std::vector<Placement> placements() {
    return {{"unit", 1.0, glm::dvec3(0.0)},
            {"scaled 1e-3", 1e-3, glm::dvec3(0.0)},
            {"scaled 1e4", 1e4, glm::dvec3(0.0)},
            {"moved 100 away", 1.0, glm::dvec3(100.0, -100.0, 100.0)},
            {"moved 1000 away", 1.0, glm::dvec3(1000.0, -1000.0, 1000.0)}};
}

// A receiver point and its normal, in the base frame.
struct Receiver {
    glm::dvec3 p;
    glm::dvec3 n;
};

glm::dvec3 tilted(double degreesFromDown, double azimuthDegrees) {
    double t = degreesFromDown * kPi / 180.0, a = azimuthDegrees * kPi / 180.0;
    return {std::sin(t) * std::cos(a), -std::cos(t), std::sin(t) * std::sin(a)};
}

std::vector<Receiver> receivers() {
    std::vector<Receiver> r;
    // Facing the light from 0.2 above its plane out to 12x its size: the elevation of the light's centre
    // falls from 90 to 2.4 degrees (the plate; its cut-off was near |x| = 0.7).
    for (double x : {0.0, -0.3, 0.5, -0.7, 0.8, -1.2, 1.6, -2.4, 3.2, 4.8})
        r.push_back({{x, 0.2, 0.05}, {0, -1, 0}});
    // Grazing: 2 cm above the light's plane, the light 1 to 12 degrees above the receiver's own horizon.
    for (double x : {-0.3, 0.4, -0.6, 1.0})
        r.push_back({{x, 0.02, -0.1}, {0, -1, 0}});
    // Tilted receivers (towards, away from and across the light), some seeing only part of the light above
    // their horizon; one facing up, with every emitter behind its tangent plane (exactly 0).
    r.push_back({{0.6, 0.3, 0.0}, tilted(45, 180)});
    r.push_back({{0.6, 0.3, 0.0}, tilted(45, 0)});
    r.push_back({{-0.1, 0.1, 0.4}, tilted(80, 90)});
    r.push_back({{0.5, 0.05, 0.1}, tilted(88, 180)});
    r.push_back({{0.0, 0.1, 0.0}, tilted(70, 30)});
    r.push_back({{2.0, 0.5, -1.0}, glm::normalize(glm::dvec3(-2.0, -0.5, 1.0))});
    r.push_back({{0.0, 0.5, 0.0}, {0, 1, 0}});
    // Behind the light's plane, facing it: a one-sided light gives exactly 0, a double-sided one its
    // back-side light.
    r.push_back({{0.1, -0.3, 0.0}, {0, 1, 0}});
    r.push_back({{1.5, -0.1, 0.5}, {0, 1, 0}});
    // Beside the light in its own plane's height band, facing it horizontally.
    r.push_back({{1.0, 0.01, 0.0}, {-1, 0, 0}});
    return r;
}

// The scene: the emitters and a tiny one-sided Lambertian square at the receiver, facing n. Returns the
// receiver's first triangle (whose centre-diagonal midpoint is the receiver point).
uint32_t buildScene(Scene& scene, const LightRig& rig, const Placement& at, const Receiver& rcv) {
    scene = Scene{};
    scene.sourcePath = "<polygon light>";
    Material receiver;
    receiver.baseColor = glm::vec3(kAlbedo);
    receiver.metallic = 0.0f;
    receiver.specular = 0.0f;
    scene.materials.push_back(receiver);
    TriangleMesh& mesh = scene.mesh;
    auto vertex = [&](const glm::dvec3& x, const glm::dvec3& n) {
        mesh.positions.push_back(glm::vec3(at.apply(x)));
        mesh.normals.push_back(glm::vec3(n));
        mesh.uv0.emplace_back(0.0f);
        mesh.uv1.emplace_back(0.0f);
        return uint32_t(mesh.positions.size() - 1);
    };
    for (const Emitter& e : rig.emitters) {
        Material light;
        light.baseColor = glm::vec3(0.0f);
        light.emission = glm::vec3(1.0f);
        light.doubleSided = e.doubleSided;
        scene.materials.push_back(light);
        uint32_t first = uint32_t(mesh.positions.size());
        for (const glm::dvec3& v : e.polygon) vertex(v, {0, 1, 0});
        for (uint32_t k = 1; k + 1 < e.polygon.size(); ++k) {  // a fan, facing +y as the polygon's winding does
            mesh.triangles.push_back({first, first + k, first + k + 1});
            mesh.materialIds.push_back(uint32_t(scene.materials.size() - 1));
        }
    }
    // The receiver: a 1 cm square (2.5% of the light's size: small enough to shadow nothing that matters,
    // large enough that float vertices 100 units from the origin keep its normal), wound to face n.
    glm::dvec3 t = glm::normalize(glm::cross(rcv.n, std::abs(rcv.n.y) < 0.9 ? glm::dvec3(0, 1, 0) : glm::dvec3(1, 0, 0)));
    glm::dvec3 b = glm::cross(rcv.n, t);
    const double h = 0.005;
    uint32_t first = vertex(rcv.p - h * t - h * b, rcv.n);
    vertex(rcv.p + h * t - h * b, rcv.n);
    vertex(rcv.p + h * t + h * b, rcv.n);
    vertex(rcv.p - h * t + h * b, rcv.n);
    uint32_t tri = uint32_t(mesh.triangles.size());
    mesh.triangles.push_back({first, first + 1, first + 2});
    mesh.triangles.push_back({first, first + 2, first + 3});
    mesh.materialIds.push_back(0);
    mesh.materialIds.push_back(0);
    scene.updateBounds();
    return tri;
}

// Exact outgoing radiance at the receiver point x (world space, as nrad interpolated it) with normal n.
double exactRadiance(const LightRig& rig, const Placement& at, const glm::dvec3& x, const glm::dvec3& n) {
    double e = 0.0;
    for (const Emitter& em : rig.emitters) {
        Polygon world;
        for (const glm::dvec3& v : em.polygon) world.push_back(glm::dvec3(glm::vec3(at.apply(v))));  // as stored
        glm::dvec3 nl = glm::normalize(glm::cross(world[1] - world[0], world[2] - world[0]));
        bool behind = glm::dot(x - world[0], nl) <= 0.0;
        if (behind && !em.doubleSided) continue;
        e += lambertPolygon(world, x, n);
    }
    return double(kAlbedo) / kPi * e;
}

// Spacing of floats at magnitude x.
float ulpOf(float x) { return std::nextafter(x, std::numeric_limits<float>::infinity()) - x; }

struct Estimate {
    double mean = 0.0, standardError = 0.0;
};

// Randomised QMC: kBatches independently scrambled streams of kSamples samples each; the standard error is
// that of the batch means.
constexpr int kBatches = 32;
constexpr int kSamples = 128;

Estimate estimate(const PathTracer& tracer, const SurfaceInteraction& si, uint32_t seed) {
    std::vector<double> means;
    RayCounters counters;
    for (int k = 0; k < kBatches; ++k) {
        uint32_t stream = hashCombine(seed, uint32_t(k));
        double sum = 0.0;
        for (int s = 0; s < kSamples; ++s) {
            Sampler sampler(stream, uint32_t(s));
            glm::vec3 L = tracer.outgoingRadiance(si, sampler, 2, counters);
            sum += double(L.y);
        }
        means.push_back(sum / kSamples);
    }
    Estimate e;
    for (double m : means) e.mean += m;
    e.mean /= kBatches;
    double v = 0.0;
    for (double m : means) v += (m - e.mean) * (m - e.mean);
    e.standardError = std::sqrt(v / (kBatches - 1) / kBatches);
    return e;
}

// Learned selection as the renderer uses it: trained on the contributions its own paths record at the
// receiver (where two lights are candidates), then frozen. Returns the training steps taken.
uint64_t train(const PathTracer& tracer, LightSelector& selector, const SurfaceInteraction& si, uint32_t seed) {
    std::vector<NeeRecord> records;
    NeeTrace trace;
    trace.records = &records;
    RayCounters counters;
    for (uint32_t round = 0; round < 16; ++round) {
        records.clear();
        for (uint32_t s = 0; s < 64; ++s) {
            Sampler sampler(hashCombine(seed, 0x5eed0000u + round), s);
            tracer.outgoingRadiance(si, sampler, 2, counters, &trace);
        }
        selector.train(records);
    }
    selector.setTraining(false);
    return selector.trainingSteps();
}

struct Mode {
    const char* name;
    NeeMode mode;
    bool selector;
};

TEST(PolygonLights, DirectLightMatchesLambertsFormulaEverywhere) {
    const Mode modes[] = {{"power sampler", NeeMode::Power, false},
                          {"uniform", NeeMode::Uniform, true},
                          {"learned", NeeMode::Learned, true}};
    double sumZ2 = 0.0, maxZ = 0.0, maxRelative = 0.0;
    uint64_t trainedSteps = 0;
    int lit = 0, dark = 0;
    uint32_t seed = 1;
    for (const LightRig& rig : lightRigs())
        for (const Placement& at : placements())
            for (const Receiver& rcv : receivers()) {
                Scene scene;
                uint32_t tri = buildScene(scene, rig, at, rcv);
                Accel accel(scene);
                LightSampler lights(scene);
                ASSERT_EQ(lights.groupCount(), rig.emitters.size());
                const glm::vec3 big = glm::max(glm::abs(scene.bounds.lower), glm::abs(scene.bounds.upper));
                const float sceneMagnitude = std::max(big.x, std::max(big.y, big.z));
                Hit hit;
                hit.t = 1.0f;
                hit.triangle = tri;
                hit.u = 0.0f;  // midpoint of the diagonal from vertex 0 to vertex 2: the receiver point
                hit.v = 0.5f;
                glm::vec3 nWorld = glm::vec3(rcv.n);
                SurfaceInteraction si = makeInteraction(scene, hit, -nWorld);
                ASSERT_TRUE(si.frontFace);
                const double exact = exactRadiance(rig, at, glm::dvec3(si.p), rcv.n);
                for (const Mode& mode : modes) {
                    NeeSettings ns;
                    ns.mode = mode.mode;
                    ns.seed = seed;
                    LightSelector selector(lights, scene.bounds, ns);
                    PathTracer tracer(scene, accel, lights, mode.selector ? &selector : nullptr);
                    if (mode.mode == NeeMode::Learned) trainedSteps += train(tracer, selector, si, seed);
                    Estimate e = estimate(tracer, si, ++seed);
                    std::string where = rig.name + ", " + at.name + ", " + mode.name + ", receiver (" +
                                        std::to_string(rcv.p.x) + ", " + std::to_string(rcv.p.y) + ", " +
                                        std::to_string(rcv.p.z) + ") normal (" + std::to_string(rcv.n.x) + ", " +
                                        std::to_string(rcv.n.y) + ", " + std::to_string(rcv.n.z) + ")";
                    if (exact == 0.0) {
                        EXPECT_EQ(e.mean, 0.0) << where;
                        ++dark;
                        continue;
                    }
                    // The standard error, with a floor of float rounding where the QMC estimate is nearly
                    // exact: 1e-5 of the value, plus the spacing of floats at the scene's largest coordinate
                    // relative to its size (1 m in the base frame; 6e-5 at 1000 m from the origin).
                    const double rounding = 1e-5 + double(ulpOf(sceneMagnitude)) / at.scale;
                    double sigma = std::sqrt(e.standardError * e.standardError + rounding * rounding * exact * exact);
                    double z = (e.mean - exact) / sigma;
                    EXPECT_LT(std::abs(z), 6.0) << where << ": nrad " << e.mean << ", exact " << exact
                                                << ", ratio " << e.mean / exact << ", standard error " << e.standardError;
                    EXPECT_LT(e.standardError, 0.05 * exact) << where;  // the check has teeth everywhere
                    sumZ2 += z * z;
                    maxZ = std::max(maxZ, std::abs(z));
                    maxRelative = std::max(maxRelative, std::abs(e.mean / exact - 1.0));
                    ++lit;
                }
            }
    // Over all lit receivers the squared deviations average about 1 (slightly more for 31 degrees of
    // freedom, 1.07; the spread of that mean over 900 receivers is about 0.05): a bias of one standard error
    // everywhere would double it.
    std::printf("%d lit receivers: mean squared deviation %.3f standard errors^2, largest %.2f standard errors, "
                "largest relative difference %.2e; %d dark receivers exactly 0\n",
                lit, sumZ2 / lit, maxZ, maxRelative, dark);
    ASSERT_GT(lit, 100);
    EXPECT_GT(trainedSteps, 1000u);  // learned selection was trained where it has a choice
    EXPECT_GT(dark, 10);
    EXPECT_LT(sumZ2 / lit, 1.25) << lit << " lit receivers";
}

TEST(RayMargins, NoSelfShadowOnALargeTiltedPlaneThroughTheOrigin) {
    // A 2 km tilted Lambertian square through (nearly) the origin under a sun: direct light at any point is
    // exactly (a / pi) E cos. Margins taken from the point's own coordinates let 46% of the shadow rays near
    // the origin find their own triangle (Embree's rounding scales with the triangle's coordinates).
    Scene scene;
    Material m;
    m.baseColor = glm::vec3(kAlbedo);
    m.metallic = 0.0f;
    m.specular = 0.0f;
    scene.materials.push_back(m);
    const glm::vec3 n = glm::normalize(glm::vec3(0.3f, 0.9f, 0.35f));
    const glm::vec3 t = glm::normalize(glm::cross(n, glm::vec3(1, 0, 0))), b = glm::cross(n, t);
    TriangleMesh& mesh = scene.mesh;
    for (glm::vec2 c : {glm::vec2(-1, -1), glm::vec2(1, -1), glm::vec2(1, 1), glm::vec2(-1, 1)}) {
        mesh.positions.push_back(1000.0f * (c.x * t + c.y * b) + glm::vec3(0.3f, -0.2f, 0.1f) * 1e-3f);
        mesh.normals.push_back(n);
        mesh.uv0.emplace_back(0.0f);
        mesh.uv1.emplace_back(0.0f);
    }
    mesh.triangles = {{0, 1, 2}, {0, 2, 3}};
    mesh.materialIds = {0, 0};
    PunctualLight sun;
    sun.type = PunctualLight::Type::Directional;
    sun.direction = -glm::normalize(n + 0.8f * t);  // 39 degrees from the normal
    sun.intensity = glm::vec3(1.0f);
    scene.lights.push_back(sun);
    scene.updateBounds();
    Accel accel(scene);
    LightSampler lights(scene);
    PathTracer tracer(scene, accel, lights);
    const double exact = double(kAlbedo) / kPi * double(glm::dot(n, -sun.direction));
    int points = 0;
    for (float reach : {1e-3f, 1.0f, 900.0f})
        for (int i = 0; i < 500; ++i) {
            glm::vec3 onPlane = reach * (std::sin(float(i)) * t + std::cos(1.3f * float(i)) * b);
            Hit hit = accel.intersect(onPlane + 10.0f * n, -n);
            ASSERT_TRUE(hit.valid());
            SurfaceInteraction si = makeInteraction(scene, hit, -n);
            RayCounters counters;
            Sampler sampler(7, uint32_t(i));
            double L = tracer.outgoingRadiance(si, sampler, 2, counters).y;
            ASSERT_NEAR(L, exact, 1e-5 * exact) << "point " << i << " at " << reach << " from the origin";
            ++points;
        }
    EXPECT_EQ(points, 1500);
}

}  // namespace
}  // namespace nrad
