// The optimizer of every network the baker trains (the voxel networks, baker/bake, and the light-selection
// network, baker/lights): Adam, and a moving average of the parameters it steps.
#pragma once

#include <cstddef>
#include <cstdint>
#include <vector>

namespace nrad {

class Adam {
public:
    // The usual moments' decays and epsilon; no other argument, so that nothing converts into them (a learning rate
    // passed here was once taken for beta1).
    explicit Adam(size_t parameterCount);
    // One step at this learning rate (the caller's schedule).
    void step(std::vector<float>& params, const std::vector<float>& grad, float learningRate);

private:
    std::vector<float> m_, v_;
    static constexpr float beta1_ = 0.9f, beta2_ = 0.999f, epsilon_ = 1e-8f;
    double beta1Power_ = 1.0, beta2Power_ = 1.0;
};

// Exponential moving average of parameters over optimizer steps (Polyak averaging): what is kept when the
// gradients are noisy, as with one-bounce targets. average = decay average + (1 - decay) params.
inline void updateAverage(std::vector<float>& average, const std::vector<float>& params, float decay) {
    for (size_t q = 0; q < average.size(); ++q) average[q] = decay * average[q] + (1.0f - decay) * params[q];
}

}  // namespace nrad
