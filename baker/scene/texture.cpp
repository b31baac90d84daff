// Texture lookups and colour transfer functions.
#include "baker/scene/texture.h"

#include <array>
#include <cmath>

namespace nrad {

namespace {

int wrapIndex(int i, int n, WrapMode mode) {
    if (i >= 0 && i < n) return i;  // inside the texture every mode leaves it: no divisions in the common case
    switch (mode) {
        case WrapMode::ClampToEdge:
            return i < 0 ? 0 : (i >= n ? n - 1 : i);
        case WrapMode::MirroredRepeat: {
            int period = 2 * n;
            int m = ((i % period) + period) % period;
            return m < n ? m : period - 1 - m;
        }
        case WrapMode::Repeat:
        default:
            return ((i % n) + n) % n;
    }
}

}  // namespace

glm::vec4 Texture::sample(glm::vec2 uv) const {
    if (width <= 0 || height <= 0) return glm::vec4(1.0f);
    // Keep the coordinate in a range where float->int conversion is safe, without changing the wrap result.
    float x = uv.x * float(width) - 0.5f;
    float y = uv.y * float(height) - 0.5f;
    if (!std::isfinite(x) || !std::isfinite(y)) return average;
    const float rangeX = float(2 * width * 1024), rangeY = float(2 * height * 1024);
    if (!(std::abs(x) < rangeX)) x = std::fmod(x, rangeX);  // fmod leaves a smaller magnitude as it is
    if (!(std::abs(y) < rangeY)) y = std::fmod(y, rangeY);
    float fx = std::floor(x), fy = std::floor(y);
    float tx = x - fx, ty = y - fy;
    int x0 = int(fx), y0 = int(fy);
    int xa = wrapIndex(x0, width, wrapS), xb = wrapIndex(x0 + 1, width, wrapS);
    int ya = wrapIndex(y0, height, wrapT), yb = wrapIndex(y0 + 1, height, wrapT);
    const glm::vec4 a = texel(size_t(ya) * width + xa);
    const glm::vec4 b = texel(size_t(ya) * width + xb);
    const glm::vec4 c = texel(size_t(yb) * width + xa);
    const glm::vec4 d = texel(size_t(yb) * width + xb);
    return (a * (1.0f - tx) + b * tx) * (1.0f - ty) + (c * (1.0f - tx) + d * tx) * ty;
}

void Texture::computeAverage() {
    glm::dvec4 sum(0.0);
    const size_t n = texelCount();
    for (size_t i = 0; i < n; ++i) sum += glm::dvec4(texel(i));
    average = n == 0 ? glm::vec4(0.0f) : glm::vec4(sum / double(n));
}

float srgbToLinear(float c) {
    return c <= 0.04045f ? c / 12.92f : std::pow((c + 0.055f) / 1.055f, 2.4f);
}

const float* unitOfByte() {
    static const std::array<float, 256> table = [] {
        std::array<float, 256> t{};
        for (int v = 0; v < 256; ++v) t[size_t(v)] = float(v) / 255.0f;
        return t;
    }();
    return table.data();
}

const float* linearOfSrgbByte() {
    static const std::array<float, 256> table = [] {
        std::array<float, 256> t{};
        for (int v = 0; v < 256; ++v) t[size_t(v)] = srgbToLinear(float(v) / 255.0f);
        return t;
    }();
    return table.data();
}

float linearToSrgb(float c) {
    return c <= 0.0031308f ? 12.92f * c : 1.055f * std::pow(c, 1.0f / 2.4f) - 0.055f;
}

}  // namespace nrad
