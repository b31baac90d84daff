// Adam (Kingma and Ba 2015) with bias correction.
#include "baker/nn/adam.h"

#include <cmath>

namespace nrad {

Adam::Adam(size_t parameterCount, float learningRate, float beta1, float beta2, float epsilon)
    : m_(parameterCount, 0.0f), v_(parameterCount, 0.0f), beta1_(beta1), beta2_(beta2), epsilon_(epsilon) {
    (void)learningRate;
}

void Adam::step(std::vector<float>& params, const std::vector<float>& grad, float learningRate) {
    beta1Power_ *= beta1_;
    beta2Power_ *= beta2_;
    float c1 = float(1.0 - beta1Power_), c2 = float(1.0 - beta2Power_);
    for (size_t i = 0; i < params.size(); ++i) {
        m_[i] = beta1_ * m_[i] + (1.0f - beta1_) * grad[i];
        v_[i] = beta2_ * v_[i] + (1.0f - beta2_) * grad[i] * grad[i];
        params[i] -= learningRate * (m_[i] / c1) / (std::sqrt(v_[i] / c2) + epsilon_);
    }
}
}  // namespace nrad
