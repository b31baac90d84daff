// Small optimisation helpers shared by the per-voxel networks (baker/bake) and the light-selection network
// (baker/render): the Adam optimizer and a deterministic random generator.
#pragma once

#include <cstddef>
#include <cstdint>
#include <vector>

namespace nrad {

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
