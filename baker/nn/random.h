// The deterministic generator of network initialisation and sample order.
#pragma once

#include <cstdint>

namespace nrad {

// Deterministic 64-bit generator (SplitMix64), identical on every platform and standard library.
class SplitMix64 {
public:
    explicit SplitMix64(uint64_t seed) : state_(seed) {}
    static constexpr uint64_t kIncrement = 0x9e3779b97f4a7c15ull;
    uint64_t next() {
        uint64_t z = (state_ += kIncrement);
        z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ull;
        z = (z ^ (z >> 27)) * 0x94d049bb133111ebull;
        return z ^ (z >> 31);
    }
    float uniform() { return float(next() >> 40) * 0x1p-24f; }  // [0, 1)
    uint64_t below(uint64_t n) { return next() % n; }
    // Passes over `count` outputs and returns the state before them: the k-th of them (from 0) is next()'s mix of the
    // state plus (k + 1) kIncrement (for generators of many outputs at once).
    uint64_t skip(uint64_t count) {
        const uint64_t at = state_;
        state_ += count * kIncrement;
        return at;
    }

private:
    uint64_t state_;
};

// out[k] = below(top - k) for k < count, as `count` calls in turn give them (the draws of a Fisher-Yates shuffle
// of `top` items; 1 <= top - count + 1, top < 2^32): the training's shuffles draw one for every sample of a voxel
// in every epoch. Eight at a time with AVX-512 (F and DQ) where the CPU has it, outputs and remainders; else the
// outputs one by one and their remainders by remaindersDescending.
void drawBelowDescending(SplitMix64& rng, uint64_t top, uint32_t count, uint32_t* out);

// out[k] = x[k] % (top - k) for k < count (1 <= top - count + 1, top < 2^32), exact without a 64-bit division: x in
// three digits of 22, 21 and 21 bits, each step's remainder from a double quotient corrected by one (random.cpp,
// random_avx512.cpp); eight at a time with AVX-512 (F and DQ) where the CPU has it, else one by one (the same bits:
// both exact).
void remaindersDescending(const uint64_t* x, uint64_t top, uint32_t count, uint32_t* out);
// The one-by-one path, for tests on machines that have AVX-512.
void remaindersDescendingScalar(const uint64_t* x, uint64_t top, uint32_t count, uint32_t* out);

}  // namespace nrad
