// Adam (Kingma and Ba 2015) with bias correction.
#include "baker/nn/adam.h"

#include <cmath>

#include "baker/nn/mlp_batch.h"  // cpuHasAvx2

namespace nrad {

namespace {

// One step over n parameters. Distinct arrays (restrict) and no errno from sqrt (-fno-math-errno): the loop
// vectorises, each element's operations and their order unchanged (IEEE multiply, add, divide and square
// root, no fused multiply-add), so every vector width gives the same bits.
__attribute__((always_inline)) inline void adamLoop(float* __restrict p, float* __restrict m, float* __restrict v,
                                                    const float* __restrict g, size_t n, float b1, float b2, float eps,
                                                    float c1, float c2, float learningRate) {
    for (size_t i = 0; i < n; ++i) {
        m[i] = b1 * m[i] + (1.0f - b1) * g[i];
        v[i] = b2 * v[i] + (1.0f - b2) * g[i] * g[i];
        p[i] -= learningRate * (m[i] / c1) / (std::sqrt(v[i] / c2) + eps);
    }
}

void adamBaseline(float* p, float* m, float* v, const float* g, size_t n, float b1, float b2, float eps, float c1, float c2,
                  float lr) {
    adamLoop(p, m, v, g, n, b1, b2, eps, c1, c2, lr);
}

#if defined(__x86_64__)
__attribute__((target("avx2"))) void adamAvx2(float* p, float* m, float* v, const float* g, size_t n, float b1, float b2,
                                              float eps, float c1, float c2, float lr) {
    adamLoop(p, m, v, g, n, b1, b2, eps, c1, c2, lr);
}
#endif

}  // namespace

Adam::Adam(size_t parameterCount) : m_(parameterCount, 0.0f), v_(parameterCount, 0.0f) {}

void Adam::step(std::vector<float>& params, const std::vector<float>& grad, float learningRate) {
    beta1Power_ *= beta1_;
    beta2Power_ *= beta2_;
    const float c1 = float(1.0 - beta1Power_), c2 = float(1.0 - beta2Power_);
#if defined(__x86_64__)
    if (cpuHasAvx2())
        return adamAvx2(params.data(), m_.data(), v_.data(), grad.data(), params.size(), beta1_, beta2_, epsilon_, c1, c2,
                        learningRate);
#endif
    adamBaseline(params.data(), m_.data(), v_.data(), grad.data(), params.size(), beta1_, beta2_, epsilon_, c1, c2, learningRate);
}

}  // namespace nrad
