// LightSampler: chooses among the scene's lights (light.h: emissive triangles, KHR_lights_punctual point,
// spot and directional lights, the environment) in proportion to their power, for next event estimation, and
// answers the pdf of having sampled a given emitter point or direction (for MIS).
//
// For light selection (uniform, learned) the entries are also grouped into *lights* as a user sees them:
// the emissive triangles of one material that share vertices form one light (a quad, a lamp shade), each
// punctual light is one, the environment is one. Beyond kMaxLightGroups lights, lights are merged into spatial
// clusters (repeated median splits of the largest cluster along its longest axis). Within a group an entry is
// picked by power.
#pragma once

#include <cstdint>
#include <memory>
#include <vector>

#include <glm/glm.hpp>

#include "baker/lights/environment_light.h"
#include "baker/lights/light.h"
#include "baker/scene/scene.h"

namespace nrad {

// The interval of `cdf` (ascending) that u falls in: std::upper_bound's index (the first entry above u; NaN
// compares as upper_bound compares it), at most the last. Found without branches: a light pick is a coin flip for
// the branch predictor, which would mispredict about once per halving.
size_t cdfInterval(const std::vector<double>& cdf, float u);

class LightSampler {
public:
    explicit LightSampler(const Scene& scene);

    bool empty() const { return lights_.empty(); }
    size_t lightCount() const { return lights_.size(); }
    double totalPower() const { return totalPower_; }

    // u.x chooses the light and, rescaled within the light's share, is the point's first coordinate; u.y is
    // its second. A stratified u.x thus stratifies the points on each light as well.
    LightSample sample(const glm::vec3& p, glm::vec2 u) const;

    // The part of sample(p, u) that does not depend on p, where u picks a quad light (a parallelogram group)
    // without an emissive texture: the point on it and what TriangleLight::sampleAt needs of the triangle
    // the point lands in, for the rest of the sample in SIMD lanes (baker/render/scatter_lanes.h). False where u
    // picks any other light (then sample() is the way).
    struct QuadPick {
        glm::vec3 point;  // on the light
        glm::vec3 normal;  // TriangleLight::normal()
        glm::vec3 front, back;  // radiance towards either side
        float area = 0.0f, margin = 0.0f;
        float pick = 0.0f;  // probability of the entry (sample()'s pdf is sampleAt's times this)
    };
    bool pickQuad(glm::vec2 u, QuadPick& out) const;

    // Solid-angle pdf with which sample() produces point pLight (with normal nLight) on emissive
    // triangle `triangle`, seen from p. Zero for triangles that are not lights.
    float pdfTriangle(uint32_t triangle, const glm::vec3& p, const glm::vec3& pLight, const glm::vec3& nLight) const;

    // The lights that a ray leaving the scene along wi meets (the environment, soft suns whose disk holds
    // wi): f(Le, pdf, group, pdfInGroup) for each, pdf the solid-angle pdf with which sample() produces wi for
    // that light, pdfInGroup the same without the group's probability (sampleGroup's).
    template <typename F>
    void forEachEscaped(const glm::vec3& wi, F&& f) const {
        for (uint32_t i : escapedEntries_) {
            glm::vec3 Le;
            float pdf;
            if (!lights_[i]->escaped(wi, Le, pdf)) continue;
            if (Le.x > 0.0f || Le.y > 0.0f || Le.z > 0.0f) f(Le, pickProbability(i) * pdf, groupOfEntry_[i], pickInGroup_[i] * pdf);
        }
    }

    // Light entry i (for tests and tools).
    const Light& light(size_t i) const { return *lights_[i]; }

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
        // Two triangles forming a parallelogram (a quad light), sampled as one quad (sample, sampleGroup):
        // quads_[quad].
        bool parallelogram = false;
        uint32_t quad = 0;
    };
    // A parallelogram group's quad: corner + u edgeU + v edgeV, u + v <= 1 in entries[0], and per triangle
    // (entries[0], entries[1]) what pickQuad gives of it, so that a pick reads one flat record instead of
    // following the group's entries and the lights' pointers.
    struct Quad {
        glm::vec3 corner{0.0f}, edgeU{0.0f}, edgeV{0.0f};
        uint32_t entries[2] = {0, 0};
        bool textured[2] = {false, false};
        QuadPick halves[2];  // the point left unset
    };
    // Per entry of cdf_: the quad it is half of where sample() picks that quad as one (its two entries are
    // neighbours in cdf_), with the quad's interval of cdf_ (from lo, `width` wide); else quad = -1.
    struct EntryQuad {
        int32_t quad = -1;
        double lo = 0.0, width = 0.0;
    };
    // The sample of entry i (its own pdf times `pick`), with the entry recorded.
    LightSample sampleEntry(size_t i, float pick, const glm::vec3& p, const glm::vec2& u) const;
    const TriangleLight* triangleLight(size_t i) const;
    // g's power, bounds and whether it is planar, from its entries.
    void groupBounds(Group& g, const std::vector<double>& power) const;
    // Where g's two triangles form a parallelogram: sets g.parallelogram and g.quad, adds the quad to quads_.
    void detectParallelogram(Group& g, const std::vector<double>& power);
    // sample()'s pick: entry i for u.x; where it is half of a quad that sample() picks as one (entryQuad_),
    // that quad, with u.x rescaled over both halves (else nullptr, u unchanged).
    const Quad* pickEntry(glm::vec2& u, size_t& i) const;
    // The point for u on `quad` and which half (0, 1) it lies in.
    static int quadPoint(const Quad& quad, const glm::vec2& u, glm::vec3& pl);
    // globalPick: the pdf includes the entry's probability in the whole list (sample()), else in its group.
    LightSample sampleParallelogram(const Quad& quad, const glm::vec3& p, const glm::vec2& u, bool globalPick) const;
    const Scene& scene_;
    EnvironmentSampler environment_;
    std::vector<std::unique_ptr<Light>> lights_;
    std::vector<double> cdf_;  // cumulative power, normalised to end at 1
    std::vector<float> pick_;  // per entry: its interval of cdf_ (the probability of picking it)
    std::vector<int32_t> entryOfTriangle_;  // triangle -> entry, -1 if not emissive
    std::vector<uint32_t> escapedEntries_;  // lights at infinity: what rays leaving the scene meet
    int32_t environmentEntry_ = -1;
    double totalPower_ = 0.0;
    std::vector<Group> groups_;
    std::vector<uint32_t> groupOfEntry_;
    std::vector<float> pickInGroup_;  // per entry: probability of the entry given its group
    std::vector<Quad> quads_;  // of the parallelogram groups
    std::vector<EntryQuad> entryQuad_;  // per entry
    float sceneRadius_ = 1.0f;
};

}  // namespace nrad
