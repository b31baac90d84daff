// Texture: a decoded image in linear float RGBA with its glTF sampler wrap modes, bilinear lookups.
#pragma once

#include <vector>

#include <glm/glm.hpp>

namespace nrad {

enum class WrapMode { Repeat, ClampToEdge, MirroredRepeat };

struct Texture {
    int width = 0;
    int height = 0;
    std::vector<glm::vec4> texels;  // row-major, top row first, linear values
    WrapMode wrapS = WrapMode::Repeat;
    WrapMode wrapT = WrapMode::Repeat;
    glm::vec4 average{0.0f};  // mean texel, for light power estimates

    // Bilinear lookup at uv (glTF convention: v = 0 is the top row).
    glm::vec4 sample(glm::vec2 uv) const;
    void computeAverage();
};

// sRGB transfer function, decoding (0..1 -> linear) and encoding (linear -> 0..1).
float srgbToLinear(float c);
float linearToSrgb(float c);

}  // namespace nrad
