// Texture lookups and colour transfer functions.
#include "baker/scene/texture.h"

#include <array>
#include <cmath>

#if defined(__linux__)
#include <sys/mman.h>
#endif

namespace nrad {

namespace detail {

namespace {
constexpr std::size_t kLargePage = std::size_t(2) << 20;
}

void* allocateLarge(std::size_t bytes) {
    if (bytes < kLargePage) {
        void* p = std::malloc(bytes == 0 ? 1 : bytes);
        if (!p) throw std::bad_alloc();
        return p;
    }
    const std::size_t rounded = (bytes + kLargePage - 1) / kLargePage * kLargePage;
    void* p = std::aligned_alloc(kLargePage, rounded);
    if (!p) throw std::bad_alloc();
#if defined(__linux__) && defined(MADV_HUGEPAGE)
    madvise(p, rounded, MADV_HUGEPAGE);  // advice only: without transparent huge pages nothing changes
#endif
    return p;
}

void freeLarge(void* p) noexcept { std::free(p); }

}  // namespace detail

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
    float x = uv.x * float(width) - 0.5f;
    float y = uv.y * float(height) - 0.5f;
    // Keep the coordinate in a range where float->int conversion is safe, without changing the wrap result (one
    // test for the common case; not finite fails it too).
    const float rangeX = float(2 * width * 1024), rangeY = float(2 * height * 1024);
    if (!(std::abs(x) < rangeX) || !(std::abs(y) < rangeY)) [[unlikely]] {
        if (!std::isfinite(x) || !std::isfinite(y)) return average;
        if (!(std::abs(x) < rangeX)) x = std::fmod(x, rangeX);  // fmod leaves a smaller magnitude as it is
        if (!(std::abs(y) < rangeY)) y = std::fmod(y, rangeY);
    }
    const float fx = std::floor(x), fy = std::floor(y);
    const float tx = x - fx, ty = y - fy;
    const int x0 = int(fx), y0 = int(fy);
    // The four texels: row-major neighbours where the footprint lies inside the image (no wrapping), else wrapped.
    size_t ia, ib, ic, id;
    if (unsigned(x0) < unsigned(width - 1) && unsigned(y0) < unsigned(height - 1)) [[likely]] {
        ia = size_t(y0) * size_t(width) + size_t(x0);
        ib = ia + 1;
        ic = ia + size_t(width);
        id = ic + 1;
    } else {
        const size_t xa = size_t(wrapIndex(x0, width, wrapS)), xb = size_t(wrapIndex(x0 + 1, width, wrapS));
        const size_t ya = size_t(wrapIndex(y0, height, wrapT)), yb = size_t(wrapIndex(y0 + 1, height, wrapT));
        ia = ya * size_t(width) + xa;
        ib = ya * size_t(width) + xb;
        ic = yb * size_t(width) + xa;
        id = yb * size_t(width) + xb;
    }
    const glm::vec4 a = texel(ia), b = texel(ib), c = texel(ic), d = texel(id);
    return (a * (1.0f - tx) + b * tx) * (1.0f - ty) + (c * (1.0f - tx) + d * tx) * ty;
}

namespace {
// A prefetch hint as an instruction the compiler keeps: GCC drops __builtin_prefetch from a function it finds
// otherwise free of side effects (and so calls to it), which would silently make these hints nothing.
inline void prefetchLine(const void* p) {
#if defined(__GNUC__) && (defined(__x86_64__) || defined(__i386__))
    asm volatile("prefetcht0 %0" : : "m"(*static_cast<const char*>(p)));
#elif defined(__GNUC__) && defined(__aarch64__)
    asm volatile("prfm pldl1keep, %0" : : "Q"(*static_cast<const char*>(p)));
#else
    (void)p;
#endif
}
}  // namespace

void Texture::prefetch(glm::vec2 uv) const {
    if (width <= 0 || height <= 0) return;
    const float x = uv.x * float(width) - 0.5f, y = uv.y * float(height) - 0.5f;
    // The footprint's top-left texel and the one below it (their rows' cache lines); outside the image (where
    // sample() wraps) nothing: rare, and a hint is not worth the wrapping.
    if (!(x >= 0.0f && x < float(width - 1) && y >= 0.0f && y < float(height - 1))) return;
    const size_t i = size_t(y) * size_t(width) + size_t(x);
    if (bytes.empty()) {
        prefetchLine(&texels[i]);
        prefetchLine(&texels[i + size_t(width)]);
    } else {
        prefetchLine(&bytes[4 * i]);
        prefetchLine(&bytes[4 * (i + size_t(width))]);
    }
}

void Texture::computeAverage() {
    glm::dvec4 sum(0.0);
    const size_t n = texelCount();
    for (size_t i = 0; i < n; ++i) sum += glm::dvec4(texel(i));
    average = n == 0 ? glm::vec4(0.0f) : glm::vec4(sum / double(n));
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

}  // namespace nrad
