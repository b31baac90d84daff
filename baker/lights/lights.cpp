// The kinds of light: emissive triangles, punctual lights (point, spot, sharp and soft directional), the
// environment.
#include "baker/lights/light.h"

#include <algorithm>
#include <cmath>
#include <limits>

#include "baker/lights/environment_light.h"
#include "baker/scene/geometry.h"
#include "baker/scene/material_lookup.h"
#include "baker/util/maths.h"

namespace nrad {

namespace {

// Solid angle of a soft sun's disk and sin^2 of its angular radius. sin^2 = (1 - c)(1 + c): 1 - c is exact
// (c >= 1/2) and the rest two roundings, where 1 - c * c lost c * c's rounding, up to 1e-4 of a small disk's
// sin^2 (a 2-degree sun's irradiance 7.5e-5 low; issue 37, tests/baker/lights/soft_sun_test.cpp).
void softSunDisk(const PunctualLight& l, float& solidAngle, float& sin2) {
    const float c = std::clamp(l.cosAngularRadius, -1.0f, 1.0f);
    solidAngle = float(2.0 * kPiDouble) * (1.0f - c);
    sin2 = std::max(0.0f, (1.0f - c) * (1.0f + c));
}

// Radiance and direction pdf of soft sun l along wi; false outside its disk.
bool softSunRadiance(const PunctualLight& l, const glm::vec3& wi, glm::vec3& Le, float& pdf) {
    if (!(glm::dot(wi, -l.direction) >= l.cosAngularRadius)) return false;
    float omega, sin2;
    softSunDisk(l, omega, sin2);
    if (!(omega > 0.0f) || !(sin2 > 0.0f)) return false;
    Le = l.intensity / (float(kPiDouble) * sin2);  // E = integral of Le cos over the disk = Le pi sin^2(radius)
    pdf = 1.0f / omega;
    return true;
}

// A KHR_lights_punctual light, or a command-line sun: point, spot, sharp (delta) or soft directional.
class PunctualSource final : public Light {
public:
    PunctualSource(const PunctualLight& light, double power, const glm::vec3& sceneCenter)
        : light_(light), power_(power), sceneCenter_(sceneCenter) {}
    double power() const override { return power_; }
    LightSample sample(const glm::vec3& p, glm::vec2 u) const override {
        if (!light_.soft()) return punctualLightSample(light_, p);
        // Uniform over the disk's cone around the direction towards the light.
        LightSample ls;
        float omega, sin2;
        softSunDisk(light_, omega, sin2);
        // 1 - cos(theta) uniform in [0, 1 - c]; sin from it without cancellation (1 - cosT^2 near the centre
        // kept a few bits of a small disk's sine).
        const float oneMinusCos = u.x * (1.0f - light_.cosAngularRadius);
        const float cosT = 1.0f - oneMinusCos, sinT = std::sqrt(std::max(0.0f, oneMinusCos * (2.0f - oneMinusCos)));
        const float phi = float(2.0 * kPiDouble) * u.y;
        Frame frame = Frame::fromNormal(-light_.direction);
        ls.wi = glm::normalize(frame.toWorld(glm::vec3(sinT * std::cos(phi), sinT * std::sin(phi), cosT)));
        ls.distance = std::numeric_limits<float>::infinity();
        ls.Li = light_.intensity / (float(kPiDouble) * sin2);
        ls.pdf = 1.0f / omega;
        return ls;
    }
    Bounds3 bounds() const override {
        Bounds3 b;
        if (!unbounded()) b.extend(light_.position);
        return b;
    }
    glm::vec3 center() const override { return unbounded() ? sceneCenter_ : light_.position; }
    bool unbounded() const override { return light_.type == PunctualLight::Type::Directional; }
    bool escaped(const glm::vec3& wi, glm::vec3& Le, float& pdf) const override {
        return light_.soft() && softSunRadiance(light_, wi, Le, pdf);
    }
    bool engineDrawn() const override { return light_.runtimeDirect; }

private:
    const PunctualLight& light_;
    double power_;
    glm::vec3 sceneCenter_;
};

// Light from outside the scene, importance-sampled (environment_light.h).
class EnvironmentLight final : public Light {
public:
    EnvironmentLight(const Environment& env, const EnvironmentSampler& sampler, double power, const glm::vec3& sceneCenter)
        : env_(env), sampler_(sampler), power_(power), sceneCenter_(sceneCenter) {}
    double power() const override { return power_; }
    LightSample sample(const glm::vec3& /*p*/, glm::vec2 u) const override {
        LightSample ls;
        float pdf;
        ls.wi = sampler_.sample(u, pdf, ls.Li);
        if (!(pdf > 0.0f)) return LightSample{};
        ls.pdf = pdf;
        ls.distance = std::numeric_limits<float>::infinity();
        return ls;
    }
    glm::vec3 center() const override { return sceneCenter_; }
    bool unbounded() const override { return true; }
    bool escaped(const glm::vec3& wi, glm::vec3& Le, float& pdf) const override {
        Le = env_.radiance(wi);
        pdf = sampler_.pdf(wi);
        return true;
    }

private:
    const Environment& env_;
    const EnvironmentSampler& sampler_;
    double power_;
    glm::vec3 sceneCenter_;
};

}  // namespace

float spotAttenuation(const PunctualLight& light, const glm::vec3& wFromLight) {
    float cd = glm::dot(light.direction, wFromLight);
    float scale = 1.0f / std::max(0.001f, light.cosInnerCone - light.cosOuterCone);
    float offset = -light.cosOuterCone * scale;
    float t = std::clamp(cd * scale + offset, 0.0f, 1.0f);
    return t * t;
}

LightSample punctualLightSample(const PunctualLight& l, const glm::vec3& p) {
    LightSample ls;
    ls.delta = true;
    ls.pdf = 1.0f;
    if (l.type == PunctualLight::Type::Directional) {
        ls.wi = -l.direction;
        ls.distance = std::numeric_limits<float>::infinity();
        ls.Li = l.intensity;
        return ls;
    }
    glm::vec3 d = l.position - p;
    float dist2 = glm::dot(d, d);
    if (!(dist2 > 0.0f)) return LightSample{};
    float dist = std::sqrt(dist2);
    ls.wi = d / dist;
    ls.distance = dist;
    ls.lightPoint = l.position;
    ls.margin = rayOffset(l.position);
    ls.Li = l.intensity / dist2;
    if (l.type == PunctualLight::Type::Spot) ls.Li *= spotAttenuation(l, -ls.wi);
    return ls;
}

glm::vec3 skyRadiance(const Scene& scene, const glm::vec3& wi) {
    glm::vec3 L = scene.environment.radiance(wi);
    for (const PunctualLight& l : scene.lights) {
        glm::vec3 Le;
        float pdf;
        if (l.soft() && softSunRadiance(l, wi, Le, pdf)) L += Le;
    }
    return L;
}

bool skyIsUniform(const Scene& scene) {
    if (scene.environment.kind == Environment::Kind::Map) return false;
    for (const PunctualLight& l : scene.lights)
        if (l.soft()) return false;
    return true;
}

TriangleLight::TriangleLight(const Scene& scene, uint32_t triangle, double power)
    : scene_(scene), triangle_(triangle), area_(scene.mesh.triangleArea(triangle)), power_(power),
      normal_(scene.mesh.geometricNormal(triangle)), margin_(triangleMargin(scene.mesh, triangle)),
      textured_(scene.materials[scene.mesh.materialIds[triangle]].emissiveTexture.valid()),
      frontRadiance_(emittedRadiance(scene, triangle, 0.0f, 0.0f, true)),
      backRadiance_(emittedRadiance(scene, triangle, 0.0f, 0.0f, false)) {}

LightSample TriangleLight::sample(const glm::vec3& p, glm::vec2 u) const {
    const glm::uvec3& tri = scene_.mesh.triangles[triangle_];
    float su = std::sqrt(u.x);
    float b1 = su * (1.0f - u.y), b2 = su * u.y;  // uniform by area
    const auto& P = scene_.mesh.positions;
    glm::vec3 pl = (1.0f - b1 - b2) * P[tri.x] + b1 * P[tri.y] + b2 * P[tri.z];
    return sampleAt(p, pl, b1, b2);
}

LightSample TriangleLight::sampleAt(const glm::vec3& p, const glm::vec3& pl, float b1, float b2) const {
    LightSample ls;
    glm::vec3 nl = normal_;
    glm::vec3 d = pl - p;
    float dist2 = glm::dot(d, d);
    if (!(dist2 > 0.0f)) return ls;
    float dist = std::sqrt(dist2);
    glm::vec3 wi = d / dist;
    float cosLight = glm::dot(nl, -wi);
    bool front = cosLight > 0.0f;
    if (!front) nl = -nl;
    float absCos = std::abs(cosLight);
    if (!(absCos > 0.0f)) return ls;
    ls.Li = textured_ ? emittedRadiance(scene_, triangle_, b1, b2, front) : (front ? frontRadiance_ : backRadiance_);
    ls.wi = wi;
    ls.distance = dist;
    ls.pdf = dist2 / (absCos * area_);
    ls.lightPoint = pl;
    ls.lightNormal = nl;
    ls.margin = margin_;
    if (!std::isfinite(ls.pdf)) ls.pdf = 0.0f;
    return ls;
}

float TriangleLight::pdf(const glm::vec3& p, const glm::vec3& pLight, const glm::vec3& nLight) const {
    glm::vec3 d = pLight - p;
    float dist2 = glm::dot(d, d);
    float absCos = std::abs(glm::dot(nLight, d)) / std::sqrt(dist2);
    if (!(absCos > 0.0f)) return 0.0f;
    return dist2 / (absCos * area_);
}

Bounds3 TriangleLight::bounds() const {
    Bounds3 b;
    const glm::uvec3& tri = scene_.mesh.triangles[triangle_];
    for (uint32_t v : {tri.x, tri.y, tri.z}) b.extend(scene_.mesh.positions[v]);
    return b;
}

glm::vec3 TriangleLight::center() const {
    const glm::uvec3& tri = scene_.mesh.triangles[triangle_];
    const auto& P = scene_.mesh.positions;
    return (P[tri.x] + P[tri.y] + P[tri.z]) / 3.0f;
}

std::vector<std::unique_ptr<Light>> makeLights(const Scene& scene, const EnvironmentSampler& environment, float sceneRadius,
                                               int32_t* environmentIndex) {
    std::vector<std::unique_ptr<Light>> lights;
    if (environmentIndex) *environmentIndex = -1;
    const double r2 = double(sceneRadius) * double(sceneRadius);
    const glm::vec3 center = scene.bounds.empty() ? glm::vec3(0.0f) : scene.bounds.center();
    for (size_t t = 0; t < scene.mesh.triangleCount(); ++t) {
        const Material& m = scene.materials[scene.mesh.materialIds[t]];
        if (!m.emissive()) continue;
        glm::vec3 e = scene.triangleEmission(t);  // averaged over the triangle's texels: zero-power emitters are no lights
        double pw = double(scene.mesh.triangleArea(t)) * kPiDouble * luminance(e) * (m.doubleSided ? 2.0 : 1.0);
        if (pw > 0.0 && std::isfinite(pw)) lights.push_back(std::make_unique<TriangleLight>(scene, uint32_t(t), pw));
    }
    for (const PunctualLight& l : scene.lights) {
        double lum = luminance(l.intensity), pw = 0.0;
        switch (l.type) {
            case PunctualLight::Type::Point: pw = 4.0 * kPiDouble * lum; break;
            case PunctualLight::Type::Spot:
                pw = 2.0 * kPiDouble * (1.0 - 0.5 * (double(l.cosInnerCone) + double(l.cosOuterCone))) * lum;
                break;
            case PunctualLight::Type::Directional: pw = kPiDouble * r2 * lum; break;
        }
        if (pw > 0.0 && std::isfinite(pw)) lights.push_back(std::make_unique<PunctualSource>(l, pw, center));
    }
    if (environment.active()) {
        // What crosses the scene's bounding sphere: pi x mean radiance over its area (pbrt's Phi).
        double pw = 4.0 * kPiDouble * kPiDouble * r2 * luminance(scene.environment.meanRadiance());
        if (pw > 0.0 && std::isfinite(pw)) {
            if (environmentIndex) *environmentIndex = int32_t(lights.size());
            lights.push_back(std::make_unique<EnvironmentLight>(scene.environment, environment, pw, center));
        }
    }
    return lights;
}

}  // namespace nrad
