// Adam (Kingma and Ba 2015) with bias correction.
#include "baker/nn/adam.h"

#include <cmath>

namespace nrad {

Adam::Adam(size_t parameterCount) : m_(parameterCount, 0.0f), v_(parameterCount, 0.0f) {}

void Adam::step(std::vector<float>& params, const std::vector<float>& grad, float learningRate) {
    beta1Power_ *= beta1_;
    beta2Power_ *= beta2_;
    float c1 = float(1.0 - beta1Power_), c2 = float(1.0 - beta2Power_);
    // Distinct arrays (restrict) and no errno from sqrt (-fno-math-errno): the loop vectorises, each element's
    // operations and their order unchanged.
    float* __restrict p = params.data();
    float* __restrict m = m_.data();
    float* __restrict v = v_.data();
    const float* __restrict g = grad.data();
    const float b1 = beta1_, b2 = beta2_, eps = epsilon_;
    const size_t n = params.size();
    for (size_t i = 0; i < n; ++i) {
        m[i] = b1 * m[i] + (1.0f - b1) * g[i];
        v[i] = b2 * v[i] + (1.0f - b2) * g[i] * g[i];
        p[i] -= learningRate * (m[i] / c1) / (std::sqrt(v[i] / c2) + eps);
    }
}
}  // namespace nrad
