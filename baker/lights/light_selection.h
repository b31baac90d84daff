// Light selection for next event estimation (paper Sec. 4): which light group the path tracer samples at a
// vertex. Three modes:
//   power    every light entry in proportion to its emitted power (LightSampler::sample; the default),
//   uniform  every light group with the same probability (the paper's baseline),
//   learned  a network per scene, 9 inputs (position normalised to the scene bounds, shading normal,
//            direction the path arrived along), two hidden layers of 64 ReLU units, a softmax over the light
//            groups, trained online on the contributions the renderer observes (visibility included).
// The learned distribution is restricted to the groups that can contribute at all (LightSampler::
// groupCanContribute) and mixed with a uniform share over them, so every light that can contribute keeps a
// probability of at least mix / candidates, then rounded to whole units of 1 / quantum (NeeSettings):
// estimates divide by the probability actually used and stay unbiased. Where at most one group can
// contribute, the network is not evaluated.
#pragma once

#include <cstdint>
#include <vector>

#include <glm/glm.hpp>

#include "baker/lights/light_sampler.h"
#include "baker/scene/scene.h"
#include "baker/nn/adam.h"
#include "baker/nn/padded_mlp.h"

namespace nrad {

enum class NeeMode { Power, Uniform, Learned };

const char* neeModeName(NeeMode mode);

struct NeeSettings {
    NeeMode mode = NeeMode::Power;
    float mix = 0.05f;  // learned: share of the uniform distribution over the candidate groups, in (0, 1]; at 1
                        // the network is not evaluated
    int batchesPerRound = 4;  // mini-batches of 64 paths rendered between two training steps
    int trainBatches = 2;  // Adam steps per round, each on 64 of its recorded contributions
    int networkVertices = 0;  // path vertices (from the first) that evaluate the network; later ones choose
                              // uniformly among the candidate groups (cost control); 0 = every vertex
    // renderOnline, learned mode: Adam steps taken on camera paths traced before the image (not kept in the
    // image; their time counts); the network is then frozen for the whole image, so every pixel's samples
    // see one distribution and its stratified pick dimension stays stratified over the lights. Each warm-up
    // round traces as many mini-batches of 64 paths as give about trainBatches x 64 useful records. 0 = the
    // paper's variant: train between rounds of batchesPerRound mini-batches throughout the render and keep
    // every sample.
    uint32_t warmupSteps = 1024;
    // Learned: the mixed distribution is rounded to whole units of 1 / quantum (at least one unit per
    // candidate; 0 = no rounding). Nearby points then mostly get the very same distribution, so the CDF a
    // pixel's stratified pick samples invert stays the same from sample to sample and each light gets its
    // share of them exactly; the network's output otherwise varies a little over the pixel and moves the
    // interval boundaries. 64 measured best at 32 spp; at a few spp no rounding is better (nrad render
    // --nee-quantum 0): docs/design.md.
    int quantum = 64;
    float learningRate = 2e-2f;  // Adam; a warm-up decays it linearly to zero (online_render.h)
    uint32_t seed = 0;  // initial weights
    bool train = true;  // false: keep the current weights (e.g. after a warm-up)
};

constexpr int kNeeInputs = PaddedMlp::kInputs;
constexpr int kNeeHidden = PaddedMlp::kHidden;

// One network evaluation's input and what came of it: the training data.
struct NeeRecord {
    float input[kNeeInputs];
    uint64_t candidates;  // groups the softmax ranged over (bit g)
    uint32_t light;  // group chosen
    float weight;  // luminance of the unoccluded contribution / probability of the choice (> 0)
};

// The selection network (baker/nn/padded_mlp.h): 9 inputs, two hidden layers of 64, one logit per group.
using NeeNetwork = PaddedMlp;
static_assert(PaddedMlp::kMaxOutputs == int(LightSampler::kMaxLightGroups));

// A vertex where next event estimation chooses a light (pbrt's LightSampleContext): its position, geometric
// normal ng and shading normal ns on the side of wo, and its index along the path (0 = the first hit).
struct LightSampleContext {
    glm::vec3 p{0.0f}, ng{0.0f}, ns{0.0f}, wo{0.0f};  // ng = 0: no tangent-plane culling (lit from behind too)
    int depth = 0;
};

// What LightSelector::sample chose at a vertex.
struct LightChoice {
    LightSample ls;  // its pdf includes the probability of the choice
    int group = -1;  // the group chosen from the distribution (-1: chosen by power, or no group has probability)
    bool networkEvaluated = false;  // the selection network gave the distribution (then `record` holds its input)
};

// The one interface of light selection, for every mode: the light sample at a vertex, and the pdfs with which
// it would have produced a light that a BSDF sample from that vertex reached (for multiple importance sampling).
class LightSelector {
public:
    LightSelector(const LightSampler& lights, const Bounds3& sceneBounds, const NeeSettings& settings);

    NeeMode mode() const { return settings_.mode; }
    const NeeSettings& settings() const { return settings_; }
    size_t groupCount() const { return lights_.groupCount(); }
    const LightSampler& lights() const { return lights_; }
    // Whether a choice is a distribution over the light groups (uniform and learned), which the caller keeps for
    // the next vertex's pdfs (kMaxLightGroups floats a vertex); power mode chooses from the whole list by power.
    bool choosesGroups() const { return settings_.mode != NeeMode::Power && lights_.groupCount() > 0; }

    // Next event estimation's light sample at ctx. By power: LightSampler::sample. Else a group from
    // distribution() (into probs): u.x picks the group by inverting the CDF of probs and, rescaled within the
    // chosen group's share, is reused for the point on it (so stratified picks stay stratified over the lights).
    LightChoice sample(const LightSampleContext& ctx, glm::vec2 u, float* probs, NeeRecord* record) const;
    // The solid-angle pdf with which sample() at the vertex `from` (its distribution in probs) gives point pLight
    // (normal nLight) of emissive triangle `triangle`.
    float pdfTriangle(const float* probs, uint32_t triangle, const glm::vec3& from, const glm::vec3& pLight,
                      const glm::vec3& nLight) const;
    // The same for light arriving from outside the scene along a direction, from LightSampler::forEachEscaped's
    // pdf (of the whole list) and group pdf.
    float pdfEscaped(const float* probs, float pdf, uint32_t group, float pdfInGroup) const {
        return choosesGroups() ? probs[group] * pdfInGroup : pdf;
    }

    // Selection probability of every group at ctx into probs[0, groupCount) (uniform and learned modes). Returns
    // true if the network was evaluated; then `record` (if given) holds its input and candidates for the caller
    // to complete.
    bool distribution(const LightSampleContext& ctx, float* probs, NeeRecord* record) const;

    // One training step on a round's records (learned mode with train = true; otherwise nothing). Records
    // with zero weight carry no gradient and are skipped; at most trainBatches x 64 are used, spread evenly.
    // lrScale multiplies the learning rate (a schedule, e.g. decaying over a warm-up); at most maxSteps steps.
    void train(const std::vector<NeeRecord>& records, float lrScale = 1.0f, int maxSteps = 1 << 30);

    // The network's own (unmixed) softmax over the candidate groups at a vertex, for tests and pictures.
    void networkDistribution(const glm::vec3& p, const glm::vec3& ns, const glm::vec3& wo, uint64_t candidates,
                             float* probs) const;
    uint64_t candidates(const glm::vec3& p, const glm::vec3& ng) const;

    const NeeNetwork& network() const { return network_; }
    uint64_t trainingSteps() const { return steps_; }
    uint64_t rejectedSteps() const { return rejectedSteps_; }  // steps undone because weights went non-finite
    void setTraining(bool on) { settings_.train = on; }

private:
    LightSample sampleGroups(const float* probs, glm::vec2 u, const glm::vec3& p, int& chosen) const;
    void quantize(float* probs, size_t G, uint64_t mask, int count) const;
    void input(const glm::vec3& p, const glm::vec3& ns, const glm::vec3& wo, float* x) const;

    const LightSampler& lights_;
    NeeSettings settings_;
    glm::vec3 boundsCenter_{0.0f}, boundsScale_{1.0f};
    NeeNetwork network_;
    Adam adam_;
    uint64_t steps_ = 0, rejectedSteps_ = 0;
    static constexpr size_t kTrainChunk = 16;  // records per parallel gradient chunk
    std::vector<std::vector<float>> chunkGrad_;
};

}  // namespace nrad
