// The deterministic generator of network initialisation and sample order.
#pragma once

#include <cstdint>

namespace nrad {

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

// x % n without a division, for a divisor used many times: with M = ceil(2^128 / n) (remainderMultiplier(n)), x % n
// is the high word of (M x mod 2^128) n, exact for every 64-bit x and n (Lemire, Kaser and Kurz, "Faster remainder
// by direct computation", 2019). The training's shuffles draw below(i) for every i of a voxel's samples in every
// epoch; a 64-bit division each cost about as much as the sample's training step.
using Uint128 = unsigned __int128;
inline Uint128 remainderMultiplier(uint64_t n) { return ~Uint128(0) / n + 1; }
inline uint64_t remainderBy(uint64_t x, Uint128 multiplier, uint64_t n) {
    const Uint128 low = multiplier * x;
    const Uint128 bottom = (Uint128(uint64_t(low)) * n) >> 64, top = Uint128(uint64_t(low >> 64)) * n;
    return uint64_t((bottom + top) >> 64);
}

}  // namespace nrad
