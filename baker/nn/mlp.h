// Mlp: the small fully connected ReLU network of one voxel, with its parameters in the asset's layout
// (per layer: W, out x in, row-major, then b), a forward pass and backpropagation. Plain float code in the
// order nrad/eval.h's forward() sums (the networks are tiny: 9-9-3 has 120 parameters); no allocation per call
// once a workspace has seen the shape. The network piece of baker/nn: loss.h turns outputs into gradients,
// adam.h steps, schedule.h sets the rate; padded_mlp.h is the light selector's wide network.
#pragma once

#include <cstddef>
#include <cstdint>
#include <vector>

#include "baker/nn/random.h"

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
    std::vector<size_t> offset_;  // of each layer's parameters
};

}  // namespace nrad
