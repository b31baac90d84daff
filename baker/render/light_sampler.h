// LightSampler: every light of the scene (emissive triangles as area lights, KHR_lights_punctual point,
// spot and directional lights) in one list, picked in proportion to emitted power, for next event
// estimation. Also answers the pdf of having sampled a given emitter point (for MIS).
#pragma once

#include <cstdint>
#include <vector>

#include <glm/glm.hpp>

#include "baker/scene/scene.h"

namespace nrad {

struct LightSample {
    glm::vec3 wi{0.0f};  // unit direction from the shading point to the light
    float distance = 0.0f;  // to the sampled point (infinity for directional lights)
    glm::vec3 Li{0.0f};  // incident radiance (area) or irradiance-like term (delta lights) before 1/pdf
    float pdf = 0.0f;  // solid-angle pdf incl. the pick probability; for delta lights, the pick probability
    bool delta = false;
    glm::vec3 lightPoint{0.0f};  // sampled point (area and positional lights)
    glm::vec3 lightNormal{0.0f};  // area lights: the emitter's normal on the emitting side
};

class LightSampler {
public:
    explicit LightSampler(const Scene& scene);

    bool empty() const { return lights_.empty(); }
    size_t lightCount() const { return lights_.size(); }
    double totalPower() const { return totalPower_; }

    // uPick chooses the light, u the point on it.
    LightSample sample(const glm::vec3& p, float uPick, const glm::vec2& u) const;

    // Solid-angle pdf with which sample() produces point pLight (with normal nLight) on emissive
    // triangle `triangle`, seen from p. Zero for triangles that are not lights.
    float pdfTriangle(uint32_t triangle, const glm::vec3& p, const glm::vec3& pLight, const glm::vec3& nLight) const;

    // Probability of picking light entry i (for tests).
    float pickProbability(size_t i) const;

private:
    struct Entry {
        bool triangle;
        uint32_t index;  // triangle index or index into Scene::lights
        float area;  // triangles only
    };
    const Scene& scene_;
    std::vector<Entry> lights_;
    std::vector<double> cdf_;  // cumulative power, normalised to end at 1
    std::vector<int32_t> entryOfTriangle_;  // triangle -> entry, -1 if not emissive
    double totalPower_ = 0.0;
    float sceneRadius_ = 1.0f;
};

// Angular falloff of a KHR_lights_punctual spot light (smoothstep-like squared ramp from the spec).
float spotAttenuation(const PunctualLight& light, const glm::vec3& wFromLight);

}  // namespace nrad
