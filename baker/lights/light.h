// Light: one light of the scene as next event estimation and MIS see it (pbrt's Light / LightSampler split):
// what it emits, how a point or direction of it is sampled from a shading point, and what a ray that leaves
// the scene meets. Which light to sample is the LightSampler's business (light_sampler.h: by power, in
// groups, or learned); a Light knows nothing of the others. The kinds are an open set: emissive triangles,
// KHR_lights_punctual point / spot / directional lights (sharp or soft suns), and the environment; a new
// kind implements this interface and is created in makeLights().
#pragma once

#include <cstdint>
#include <memory>
#include <vector>

#include <glm/glm.hpp>

#include "baker/scene/scene.h"

namespace nrad {

class EnvironmentSampler;

struct LightSample {
    glm::vec3 wi{0.0f};  // unit direction from the shading point to the light
    float distance = 0.0f;  // to the sampled point (infinity for directional lights and the environment)
    glm::vec3 Li{0.0f};  // incident radiance (area) or irradiance-like term (delta lights) before 1/pdf
    float pdf = 0.0f;  // solid-angle pdf incl. the pick probability; for delta lights, the pick probability
    bool delta = false;
    glm::vec3 lightPoint{0.0f};  // sampled point (area and positional lights)
    glm::vec3 lightNormal{0.0f};  // area lights: the emitter's normal on the emitting side
    float margin = 0.0f;  // area lights: triangleMargin of the emitter's triangle; punctual: rayOffset(position)
    int32_t entry = -1;  // the LightSampler entry sampled
};

class Light {
public:
    virtual ~Light() = default;

    // Luminance-weighted emitted power in scene units, to pick lights in proportion to it.
    virtual double power() const = 0;
    // A sample seen from p, u in [0, 1)^2; its pdf is the light's own (the pick probability not included).
    virtual LightSample sample(const glm::vec3& p, glm::vec2 u) const = 0;
    // Bounds of every point that emits (empty for lights at infinity) and a representative point (clustering).
    virtual Bounds3 bounds() const { return {}; }
    virtual glm::vec3 center() const = 0;
    // At infinity (directional lights, the environment): may light any point from any side.
    virtual bool unbounded() const { return false; }
    // A ray leaving the scene along wi: the radiance it receives from this light and the solid-angle pdf with
    // which sample() produces wi. False if it does not meet the light (points, spots, sharp suns, triangles).
    virtual bool escaped(const glm::vec3& /*wi*/, glm::vec3& /*Le*/, float& /*pdf*/) const { return false; }
    // The emissive triangle of a triangle light, else -1 (area pdfs, grouping, quads).
    virtual int64_t triangle() const { return -1; }
    // Mixed lighting: the engine draws this light's direct light (PunctualLight::runtimeDirect).
    virtual bool engineDrawn() const { return false; }
};

// An emissive triangle: uniform by area over it, radiance from its material (emissive texture included).
class TriangleLight final : public Light {
public:
    TriangleLight(const Scene& scene, uint32_t triangle, double power);
    double power() const override { return power_; }
    LightSample sample(const glm::vec3& p, glm::vec2 u) const override;
    Bounds3 bounds() const override;
    glm::vec3 center() const override;
    int64_t triangle() const override { return triangle_; }
    // The sample of a given point pl (barycentrics b1, b2 of the triangle's vertices 1 and 2) and the
    // solid-angle pdf of sampling a point with normal nLight, as seen from p.
    LightSample sampleAt(const glm::vec3& p, const glm::vec3& pl, float b1, float b2) const;
    float pdf(const glm::vec3& p, const glm::vec3& pLight, const glm::vec3& nLight) const;
    float area() const { return area_; }
    // Whether its radiance varies over it (an emissive texture): else sampleAt ignores b1 and b2.
    bool textured() const { return textured_; }
    // What sampleAt uses: the geometric normal, the margin, the untextured radiance towards either side.
    const glm::vec3& normal() const { return normal_; }
    float margin() const { return margin_; }
    const glm::vec3& frontRadiance() const { return frontRadiance_; }
    const glm::vec3& backRadiance() const { return backRadiance_; }

private:
    const Scene& scene_;
    uint32_t triangle_;
    float area_;
    double power_;
    glm::vec3 normal_;  // TriangleMesh::geometricNormal, once
    float margin_;  // triangleMargin, once
    bool textured_;
    glm::vec3 frontRadiance_, backRadiance_;  // emittedRadiance towards either side, untextured
};

// The lights of the scene, in entry order: emissive triangles of positive power (index order), punctual
// lights of positive power (scene order), the environment if active. sceneRadius: the bounding sphere's
// radius (the power of lights at infinity is what crosses it). environmentIndex: the environment's entry, -1
// without one.
std::vector<std::unique_ptr<Light>> makeLights(const Scene& scene, const EnvironmentSampler& environment, float sceneRadius,
                                               int32_t* environmentIndex = nullptr);

// The exact sample of a delta light (point, spot, sharp directional) as seen from p, pdf 1.
LightSample punctualLightSample(const PunctualLight& light, const glm::vec3& p);

// Radiance arriving along wi (unit) from outside the scene: the environment and the disks of soft suns. What a
// camera ray that misses every surface sees.
glm::vec3 skyRadiance(const Scene& scene, const glm::vec3& wi);
// Whether skyRadiance is the same along every direction (no environment map, no soft suns).
bool skyIsUniform(const Scene& scene);

// Angular falloff of a KHR_lights_punctual spot light (smoothstep-like squared ramp from the spec).
float spotAttenuation(const PunctualLight& light, const glm::vec3& wFromLight);

}  // namespace nrad
