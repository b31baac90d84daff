// Texture: an image in linear RGBA (8-bit channels decoded in lookups) with its glTF sampler wrap modes,
// bilinear lookups.
#pragma once

#include <cstddef>
#include <cstdint>
#include <cstring>
#include <vector>

#include <glm/glm.hpp>

#include "baker/scene/large_pages.h"
#include "baker/util/maths.h"

namespace nrad {

// The 256 values of an 8-bit channel: v / 255, and srgbToLinear(v / 255).
const float* unitOfByte();
const float* linearOfSrgbByte();

enum class WrapMode { Repeat, ClampToEdge, MirroredRepeat };

struct Texture {
    int width = 0;
    int height = 0;
    // Row-major, top row first. An 8-bit image keeps its bytes (`bytes`, RGBA, 4 per texel; a quarter of the
    // memory, so lookups miss the cache less) and decodes them in lookups through 256-entry tables, `colour`
    // for RGB (sRGB-decoding or not) and `alpha` (unitOfByte()) for alpha: the same floats as decoding on load.
    // Other images (16-bit, or built in code) hold linear floats in `texels`. texel(i) gives either.
    std::vector<glm::vec4, LargePageAllocator<glm::vec4>> texels;
    std::vector<uint8_t, LargePageAllocator<uint8_t>> bytes;
    const float* colour = nullptr;
    const float* alpha = nullptr;
    size_t texelCount() const { return bytes.empty() ? texels.size() : bytes.size() / 4; }
    glm::vec4 texel(size_t i) const { return bytes.empty() ? texels[i] : decode(word(i)); }
    WrapMode wrapS = WrapMode::Repeat;
    WrapMode wrapT = WrapMode::Repeat;
    glm::vec4 average{0.0f};  // mean texel, for light power estimates

    // The four bytes of texel i as one little-endian word (R in the low byte; one load instead of four), and
    // their decoded value.
    uint32_t word(size_t i) const {
        const uint8_t* b = &bytes[4 * i];
        uint32_t w;
        std::memcpy(&w, b, 4);
#if defined(__BYTE_ORDER__) && __BYTE_ORDER__ == __ORDER_BIG_ENDIAN__
        w = __builtin_bswap32(w);
#endif
        return w;
    }
    glm::vec4 decode(uint32_t w) const {
        return glm::vec4(colour[w & 255u], colour[(w >> 8) & 255u], colour[(w >> 16) & 255u], alpha[w >> 24]);
    }

    // Bilinear lookup at uv (glTF convention: v = 0 is the top row).
    glm::vec4 sample(glm::vec2 uv) const;
    // Asks the memory system for the texels sample(uv) will read (a hint; no effect on any result).
    void prefetch(glm::vec2 uv) const;
    void computeAverage();
};

// sRGB transfer function, decoding (0..1 -> linear) and encoding (linear -> 0..1).

}  // namespace nrad
