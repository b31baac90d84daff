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

// Scratch space for one forward/backward pass: every layer's activations (layer 0 = the inputs) and deltas,
// one flat buffer each, sized on first use.
struct MlpWorkspace {
    std::vector<float> values, deltas;
    std::vector<size_t> at;  // offset of layer l's units
    const float* activations(size_t layer) const { return values.data() + at[layer]; }
};

// Scratch space of a mini-batch pass (forwardBatch / backwardBatch): every layer's activations and deltas
// batch-major, unit u of layer l for sample k at at[l] + u kMaxBatch + k.
struct MlpBatchWorkspace {
    static constexpr int kMaxBatch = 64;
    std::vector<float> values, deltas;
    std::vector<size_t> at;
    int count = 0;
    // Layer l's unit u over the batch's samples.
    float* value(size_t layer, int unit) { return values.data() + at[layer] + size_t(unit) * kMaxBatch; }
    float* delta(size_t layer, int unit) { return deltas.data() + at[layer] + size_t(unit) * kMaxBatch; }
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

    // The same for a mini-batch of count <= kMaxBatch samples (x: count rows of inputs), vectorised over the
    // samples: each output is the same sum as forward()'s, bit for bit. The outputs are ws.value(last, c).
    void forwardBatch(const float* x, int count, MlpBatchWorkspace& ws) const;
    // Adds the batch's summed dLoss/dParams to `grad`, given dLoss/dy in ws.delta(last, c) for c < outputs
    // (forwardBatch must have run): forward()/backward() sample by sample up to the order of the sum over the
    // samples (tests hold them to 1e-5).
    void backwardBatch(MlpBatchWorkspace& ws, float* grad) const;
    size_t layers() const { return shape_.hidden.size() + 1; }

    bool allFinite() const;

private:
    NetworkShape shape_;
    std::vector<float> params_;
    std::vector<size_t> offset_;  // of each layer's parameters
};

}  // namespace nrad
