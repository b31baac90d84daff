// LightSampler: every light of the scene (emissive triangles as area lights, KHR_lights_punctual point,
// spot and directional lights, the environment) in one list, picked in proportion to emitted power, for next event
// estimation. Also answers the pdf of having sampled a given emitter point (for MIS).
//
// For light selection (uniform, learned) the entries are also grouped into *lights* as a user sees them:
// the emissive triangles of one material that share vertices form one light (a quad, a lamp shade), each
// punctual light is one, the environment is one. Beyond kMaxLightGroups lights, lights are merged into spatial clusters (repeated
// median splits of the largest cluster along its longest axis). Within a group an entry is picked by power.
#pragma once

#include <cstdint>
#include <vector>

#include <glm/glm.hpp>

#include "baker/render/environment_light.h"
#include "baker/scene/scene.h"

namespace nrad {

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

// The exact sample of a delta light (point, spot, sharp directional) as seen from p, pdf 1.
LightSample punctualLightSample(const PunctualLight& light, const glm::vec3& p);

class LightSampler {
public:
    explicit LightSampler(const Scene& scene);

    bool empty() const { return lights_.empty(); }
    size_t lightCount() const { return lights_.size(); }
    double totalPower() const { return totalPower_; }

    // u.x chooses the light and, rescaled within the light's share, is the point's first coordinate; u.y is
    // its second. A stratified u.x thus stratifies the points on each light as well.
    LightSample sample(const glm::vec3& p, glm::vec2 u) const;

    // Solid-angle pdf with which sample() produces point pLight (with normal nLight) on emissive
    // triangle `triangle`, seen from p. Zero for triangles that are not lights.
    float pdfTriangle(uint32_t triangle, const glm::vec3& p, const glm::vec3& pLight, const glm::vec3& nLight) const;

    // The lights that a ray leaving the scene along wi meets (the environment, soft suns whose disk holds
    // wi): f(Le, pdf, group, pdfInGroup) for each, pdf the solid-angle pdf with which sample() produces wi for
    // that light, pdfInGroup the same without the group's probability (sampleGroup's).
    // Radiance and direction pdf (without pick) of soft directional light l along wi; false outside its disk.
    static bool softSunRadiance(const PunctualLight& l, const glm::vec3& wi, glm::vec3& Le, float& pdf);

    template <typename F>
    void forEachEscaped(const glm::vec3& wi, F&& f) const {
        for (uint32_t i : escapedEntries_) {
            const Entry& e = lights_[i];
            glm::vec3 Le;
            float pdf;
            if (e.kind == Entry::Kind::Environment) {
                Le = scene_.environment.radiance(wi);
                pdf = environment_.pdf(wi);
            } else if (!softSunRadiance(scene_.lights[e.index], wi, Le, pdf)) {
                continue;
            }
            if (Le.x > 0.0f || Le.y > 0.0f || Le.z > 0.0f) f(Le, pickProbability(i) * pdf, groupOfEntry_[i], pickInGroup_[i] * pdf);
        }
    }

    // Solid-angle pdf with which sample() produces direction wi towards the environment (zero without one).
    float pdfEnvironment(const glm::vec3& wi) const;
    // The same without the probability of the environment's group (for sampleGroup's MIS).
    float pdfEnvironmentInGroup(const glm::vec3& wi) const;
    // The environment's group, -1 if the scene has no active environment.
    int32_t environmentGroup() const { return environmentEntry_ < 0 ? -1 : int32_t(groupOfEntry_[size_t(environmentEntry_)]); }

    // Whether entry `entry` is a light the engine draws directly at run time (PunctualLight::runtimeDirect).
    bool engineDrawn(int32_t entry) const;

    // Probability of picking light entry i (for tests).
    float pickProbability(size_t i) const;

    // Light groups (see the top of this file).
    static constexpr size_t kMaxLightGroups = 64;
    size_t groupCount() const { return groups_.size(); }
    double groupPower(size_t g) const { return groups_[g].power; }
    // Group of emissive triangle `triangle`, -1 if it is not a light.
    int32_t groupOfTriangle(uint32_t triangle) const;
    // Group of light entry i (entries: emissive triangles in index order, then punctual lights, then the
    // environment).
    uint32_t groupOfEntry(size_t i) const { return groupOfEntry_[i]; }
    // Conservative test: can any point of group g send light to p, a point whose surface has geometric
    // normal ng (towards the side light may arrive from)? False only when the whole group lies behind the
    // tangent plane or p lies behind every emitting side of a one-sided planar group.
    bool groupCanContribute(size_t g, const glm::vec3& p, const glm::vec3& ng) const;
    // Bit g set for every group g that groupCanContribute (at most kMaxLightGroups groups).
    uint64_t candidateGroups(const glm::vec3& p, const glm::vec3& ng) const;
    // Whether group g is two triangles forming a parallelogram, sampled as one quad (sample, sampleGroup).
    bool groupIsParallelogram(size_t g) const { return groups_[g].parallelogram; }
    // Samples a point of group g (entry by power within the group, u.x reused as in sample()); the pdf does
    // not include the probability of having chosen the group.
    LightSample sampleGroup(size_t g, const glm::vec3& p, glm::vec2 u) const;
    // Solid-angle pdf of sampleGroup() producing the given emitter point, without the group probability.
    float pdfTriangleInGroup(uint32_t triangle, const glm::vec3& p, const glm::vec3& pLight, const glm::vec3& nLight) const;

private:
    LightSample sampleEntry(size_t i, float pick, const glm::vec3& p, const glm::vec2& u) const;
    float entryPdf(size_t i, float pick, const glm::vec3& p, const glm::vec3& pLight, const glm::vec3& nLight) const;
    void buildGroups(const std::vector<double>& power);

    struct Group {
        std::vector<uint32_t> entries;  // light entries, ascending
        std::vector<double> cdf;  // by power within the group, ends at 1
        double power = 0.0;
        glm::vec3 lower{0.0f}, upper{0.0f};  // bounds of every emitting point (area and positional lights)
        glm::vec3 center{0.0f}, half{0.0f};  // of that box
        float diagonal = 0.0f;
        bool unbounded = false;  // holds a directional light or the environment: may contribute anywhere
        bool planar = false;  // one-sided triangles that share one normal (`normal`)
        glm::vec3 normal{0.0f};
        // Two triangles forming a parallelogram (a quad light): corner + u edgeU + v edgeV, u + v <= 1 in
        // entries[0]; sampled as one quad (sample, sampleGroup).
        bool parallelogram = false;
        glm::vec3 corner{0.0f}, edgeU{0.0f}, edgeV{0.0f};
    };
    struct Entry {
        enum class Kind : uint8_t { Triangle, Punctual, Environment };
        Kind kind;
        uint32_t index;  // triangle index, index into Scene::lights, or 0 (the environment)
        float area;  // triangles only
        bool triangle() const { return kind == Kind::Triangle; }
    };
    LightSample pointOnTriangle(size_t i, float pick, const glm::vec3& p, const glm::vec3& pl, float b1, float b2) const;
    LightSample punctualSample(const Entry& e, float pick, const glm::vec3& p, const glm::vec2& u) const;
    LightSample environmentSample(float pick, const glm::vec2& u) const;
    void detectParallelogram(Group& g, const std::vector<double>& power) const;
    // globalPick: the pdf includes the entry's probability in the whole list (sample()), else in its group.
    LightSample sampleParallelogram(const Group& group, const glm::vec3& p, const glm::vec2& u, bool globalPick) const;
    const Scene& scene_;
    std::vector<Entry> lights_;
    std::vector<double> cdf_;  // cumulative power, normalised to end at 1
    std::vector<int32_t> entryOfTriangle_;  // triangle -> entry, -1 if not emissive
    std::vector<uint32_t> escapedEntries_;  // the environment and soft suns
    EnvironmentSampler environment_;
    int32_t environmentEntry_ = -1;
    double totalPower_ = 0.0;
    std::vector<Group> groups_;
    std::vector<uint32_t> groupOfEntry_;
    std::vector<float> pickInGroup_;  // per entry: probability of the entry given its group
    float sceneRadius_ = 1.0f;
};

// Radiance arriving along wi (unit) from outside the scene: the environment and the disks of soft suns. What a
// camera ray that misses every surface sees.
glm::vec3 skyRadiance(const Scene& scene, const glm::vec3& wi);

// Angular falloff of a KHR_lights_punctual spot light (smoothstep-like squared ramp from the spec).
float spotAttenuation(const PunctualLight& light, const glm::vec3& wFromLight);

}  // namespace nrad
