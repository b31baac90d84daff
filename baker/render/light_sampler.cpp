// Power-proportional light selection and per-light sampling.
#include "baker/render/light_sampler.h"

#include <algorithm>
#include <cmath>

#include "baker/render/surface.h"

namespace nrad {

namespace {
constexpr double kPi = 3.14159265358979323846;
double luminance(const glm::vec3& c) { return 0.2126 * c.x + 0.7152 * c.y + 0.0722 * c.z; }
}  // namespace

float spotAttenuation(const PunctualLight& light, const glm::vec3& wFromLight) {
    float cd = glm::dot(light.direction, wFromLight);
    float scale = 1.0f / std::max(0.001f, light.cosInnerCone - light.cosOuterCone);
    float offset = -light.cosOuterCone * scale;
    float t = std::clamp(cd * scale + offset, 0.0f, 1.0f);
    return t * t;
}

LightSampler::LightSampler(const Scene& scene) : scene_(scene) {
    sceneRadius_ = std::max(scene.bounds.radius(), 1e-30f);
    entryOfTriangle_.assign(scene.mesh.triangleCount(), -1);
    std::vector<double> power;
    for (size_t t = 0; t < scene.mesh.triangleCount(); ++t) {
        const Material& m = scene.materials[scene.mesh.materialIds[t]];
        if (!m.emissive()) continue;
        glm::vec3 e = m.emission;
        if (m.emissiveTexture.valid()) e *= glm::vec3(scene.textures[size_t(m.emissiveTexture.texture)].average);
        float area = scene.mesh.triangleArea(t);
        double pw = double(area) * kPi * luminance(e) * (m.doubleSided ? 2.0 : 1.0);
        if (!(pw > 0.0) || !std::isfinite(pw)) continue;
        entryOfTriangle_[t] = int32_t(lights_.size());
        lights_.push_back({true, uint32_t(t), area});
        power.push_back(pw);
    }
    for (size_t i = 0; i < scene.lights.size(); ++i) {
        const PunctualLight& l = scene.lights[i];
        double lum = luminance(l.intensity), pw = 0.0;
        switch (l.type) {
            case PunctualLight::Type::Point: pw = 4.0 * kPi * lum; break;
            case PunctualLight::Type::Spot:
                pw = 2.0 * kPi * (1.0 - 0.5 * (double(l.cosInnerCone) + double(l.cosOuterCone))) * lum;
                break;
            case PunctualLight::Type::Directional:
                pw = kPi * double(sceneRadius_) * double(sceneRadius_) * lum;
                break;
        }
        if (!(pw > 0.0) || !std::isfinite(pw)) continue;
        lights_.push_back({false, uint32_t(i), 0.0f});
        power.push_back(pw);
    }
    cdf_.resize(power.size());
    double sum = 0.0;
    for (size_t i = 0; i < power.size(); ++i) {
        sum += power[i];
        cdf_[i] = sum;
    }
    totalPower_ = sum;
    for (double& c : cdf_) c /= sum;
    if (!cdf_.empty()) cdf_.back() = 1.0;
}

float LightSampler::pickProbability(size_t i) const {
    return float(cdf_[i] - (i > 0 ? cdf_[i - 1] : 0.0));
}

LightSample LightSampler::sample(const glm::vec3& p, float uPick, const glm::vec2& u) const {
    LightSample ls;
    if (lights_.empty()) return ls;
    size_t i = size_t(std::upper_bound(cdf_.begin(), cdf_.end(), double(uPick)) - cdf_.begin());
    i = std::min(i, lights_.size() - 1);
    float pick = pickProbability(i);
    if (!(pick > 0.0f)) return ls;
    const Entry& e = lights_[i];
    if (e.triangle) {
        const glm::uvec3& tri = scene_.mesh.triangles[e.index];
        float su = std::sqrt(u.x);
        float b1 = su * (1.0f - u.y), b2 = su * u.y;  // uniform by area
        const auto& P = scene_.mesh.positions;
        glm::vec3 pl = (1.0f - b1 - b2) * P[tri.x] + b1 * P[tri.y] + b2 * P[tri.z];
        glm::vec3 nl = scene_.mesh.geometricNormal(e.index);
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
        ls.Li = emittedRadiance(scene_, e.index, b1, b2, front);
        ls.wi = wi;
        ls.distance = dist;
        ls.pdf = pick * dist2 / (absCos * e.area);
        ls.lightPoint = pl;
        ls.lightNormal = nl;
        if (!std::isfinite(ls.pdf)) ls.pdf = 0.0f;
        return ls;
    }
    const PunctualLight& l = scene_.lights[e.index];
    ls.delta = true;
    ls.pdf = pick;
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
    ls.Li = l.intensity / dist2;
    if (l.type == PunctualLight::Type::Spot) ls.Li *= spotAttenuation(l, -ls.wi);
    return ls;
}

float LightSampler::pdfTriangle(uint32_t triangle, const glm::vec3& p, const glm::vec3& pLight,
                                const glm::vec3& nLight) const {
    int32_t i = entryOfTriangle_[triangle];
    if (i < 0) return 0.0f;
    glm::vec3 d = pLight - p;
    float dist2 = glm::dot(d, d);
    float absCos = std::abs(glm::dot(nLight, d)) / std::sqrt(dist2);
    if (!(absCos > 0.0f)) return 0.0f;
    return pickProbability(size_t(i)) * dist2 / (absCos * lights_[size_t(i)].area);
}

}  // namespace nrad
