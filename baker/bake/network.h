// Mlp: the small fully connected ReLU network of one voxel, with its parameters in the asset's layout
// (per layer: W, out x in, row-major, then b), a forward pass, backpropagation, and the Adam optimizer.
// Deliberately plain float code: the networks are tiny (9-9-3 has 120 parameters), so clarity wins.
#pragma once

#include <cstddef>
#include <cstdint>
#include <vector>

namespace nrad {

struct NetworkShape {
    int inputs = 9;
    std::vector<int> hidden = {9};
    int outputs = 3;
    size_t parameterCount() const;
    int maxWidth() const;
};

// Scratch space for one forward/backward pass (activations per layer).
struct MlpWorkspace {
    std::vector<std::vector<float>> activations;  // [layer][unit], layer 0 = inputs
    std::vector<std::vector<float>> deltas;
};

class Mlp {
public:
    explicit Mlp(NetworkShape shape);

    const NetworkShape& shape() const { return shape_; }
    std::vector<float>& parameters() { return params_; }
    const std::vector<float>& parameters() const { return params_; }

    // He-uniform weights from a deterministic generator; hidden biases a small positive constant (fewer
    // dead ReLUs); output biases `outputBias`.
    void initialize(uint64_t seed, float outputBias);

    // y = W_L relu(... relu(W_1 x + b_1) ...) + b_L (no activation on the output: the asset's output
    // transform is applied by whoever turns y into radiance).
    void forward(const float* x, float* y, MlpWorkspace& ws) const;
    // Adds dLoss/dParams for one sample to `grad`, given dLoss/dy; forward() must have run on ws for x.
    void backward(const float* dy, MlpWorkspace& ws, float* grad) const;

    bool allFinite() const;

private:
    NetworkShape shape_;
    std::vector<float> params_;
};

class Adam {
public:
    Adam(size_t parameterCount, float learningRate, float beta1 = 0.9f, float beta2 = 0.999f, float epsilon = 1e-8f);
    void step(std::vector<float>& params, const std::vector<float>& grad, float learningRate);

private:
    std::vector<float> m_, v_;
    float beta1_, beta2_, epsilon_;
    double beta1Power_ = 1.0, beta2Power_ = 1.0;
};

// Deterministic 64-bit generator (SplitMix64), identical on every platform and standard library.
class SplitMix64 {
public:
    explicit SplitMix64(uint64_t seed) : state_(seed) {}
    uint64_t next() {
        uint64_t z = (state_ += 0x9e3779b97f4a7c15ull);
        z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ull;
        z = (z ^ (z >> 27)) * 0x94d049bb133111ebull;
        return z ^ (z >> 31);
    }
    float uniform() { return float(next() >> 40) * 0x1p-24f; }  // [0, 1)
    uint64_t below(uint64_t n) { return next() % n; }

private:
    uint64_t state_;
};

}  // namespace nrad
