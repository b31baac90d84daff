// EnvironmentSampler: importance sampling of an Environment's directions. A map is sampled by a piecewise
// constant 2D distribution over its texels weighted by luminance x sin(theta) (the Jacobian of the
// latitude-longitude mapping, so that the poles' stretched texels are not oversampled); a constant sky
// uniformly over the sphere. pdf() is the exact density of sample() for any direction, as MIS needs.
#pragma once

#include <vector>

#include <glm/glm.hpp>

#include "baker/scene/environment.h"

namespace nrad {

class EnvironmentSampler {
public:
    explicit EnvironmentSampler(const Environment& env);

    // False for an inactive or all-black environment: nothing to sample.
    bool active() const { return active_; }
    // A direction towards the environment from u in [0, 1)^2, its solid-angle pdf (> 0), and its radiance.
    glm::vec3 sample(glm::vec2 u, float& pdf, glm::vec3& radiance) const;
    // The solid-angle density with which sample() produces direction `towards` (unit).
    float pdf(const glm::vec3& towards) const;

private:
    const Environment& env_;
    bool active_ = false;
    std::vector<double> marginal_;  // H + 1 entries: cumulative row weights, 0 .. 1
    std::vector<double> conditional_;  // H x (W + 1): cumulative weights within each row, 0 .. 1
    std::vector<float> density_;  // per texel: weight / mean weight (the pdf over [0, 1]^2 in that texel)
};

}  // namespace nrad
