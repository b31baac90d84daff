// PaddedMlp: the light selector's network, 9 -> 64 -> 64 -> K, ReLU, logits out. Weights are stored input-major
// (W[i][o]) so that every layer is a sum of scaled rows, which vectorises over the outputs; the output rows
// are padded with zeros to a width of 16, 32 or 64. The same function as an Mlp of shape 9-64-64-K on the
// same weights in the asset's row-major layout (toRowMajor; tests/baker/nn holds them to each other).
#pragma once

#include <cstddef>
#include <cstdint>
#include <vector>

namespace nrad {

class PaddedMlp {
public:
    static constexpr int kInputs = 9, kHidden = 64, kMaxOutputs = 64;

    PaddedMlp(int outputs, uint64_t seed);  // outputs clamped to [1, kMaxOutputs]
    int outputs() const { return outputs_; }
    int paddedOutputs() const { return padded_; }
    std::vector<float>& parameters() { return params_; }
    const std::vector<float>& parameters() const { return params_; }

    struct Activations {
        float h1[kHidden], h2[kHidden], logits[kMaxOutputs];
    };
    void forward(const float* x, Activations& a) const;
    // Adds dLoss/dParams to grad for one input, given dLoss/dLogits (paddedOutputs() of them, zero beyond
    // outputs()); a from forward(x).
    void backward(const float* x, const Activations& a, const float* dLogits, float* grad) const;

    // The parameters (or a gradient) in the row-major layout of Mlp (per layer W out x in, then b), padding left out.
    std::vector<float> toRowMajor(const std::vector<float>& padded) const;

private:
    size_t w3() const { return size_t(kInputs) * kHidden + kHidden + size_t(kHidden) * kHidden + kHidden; }
    size_t b3() const { return w3() + size_t(kHidden) * size_t(padded_); }

    int outputs_;
    int padded_;  // output rows padded to 16, 32 or 64 (zeros) so the output layer has a fixed width
    std::vector<float> params_;
};

}  // namespace nrad
