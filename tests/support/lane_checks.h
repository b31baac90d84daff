// Shared by the lanes kernels' tests (bsdf_lanes_test, scatter_lanes_test): bitwise comparison and random unit
// directions.
#pragma once

#include <cstring>
#include <random>

#include <glm/glm.hpp>

namespace nrad::test {

inline bool sameBits(float a, float b) { return std::memcmp(&a, &b, sizeof a) == 0; }

// Uniform over the sphere (rejection from the cube).
inline glm::vec3 randomDirection(std::mt19937& rng) {
    std::uniform_real_distribution<float> u(-1.0f, 1.0f);
    for (;;) {
        glm::vec3 d(u(rng), u(rng), u(rng));
        float l = glm::length(d);
        if (l > 0.1f && l <= 1.0f) return d / l;
    }
}

}  // namespace nrad::test
