// drawBelowDescending (random.h): one by one, or eight at a time with AVX-512 (random_avx512.cpp).
#include "baker/nn/random.h"

namespace nrad {

#if defined(__x86_64__) || defined(_M_X64)
void remaindersDescendingAvx512(const uint64_t* x, uint64_t top, uint32_t count, uint32_t* out);
void drawBelowDescendingAvx512(SplitMix64& rng, uint64_t top, uint32_t count, uint32_t* out);
#endif

namespace {

// x mod n for a 64-bit x and 1 <= n < 2^32, digit by digit: each step's v = r 2^21 + d is below n 2^21 <= 2^53, so
// exact in double, and its quotient floor(v / n) from the double product v (1 / n) is off by at most one (v / n <
// 2^22, the product's rounding far below one); v - q n in integers, corrected into [0, n). Exact, so the same bits
// as any other exact remainder (random_avx512.cpp's lanes).
inline uint64_t remainderByDigits(uint64_t x, uint64_t n, double inverse) {
    auto step = [n, inverse](uint64_t v) {
        const uint64_t q = uint64_t(double(v) * inverse);  // (truncation: floor, v >= 0)
        int64_t r = int64_t(v) - int64_t(q * n);
        if (r < 0) r += int64_t(n);
        if (r >= int64_t(n)) r -= int64_t(n);
        return uint64_t(r);
    };
    uint64_t r = step(x >> 42);
    r = step((r << 21) | ((x >> 21) & 0x1fffff));
    return step((r << 21) | (x & 0x1fffff));
}

bool hasAvx512dq() {
#if defined(__x86_64__) || defined(_M_X64)
    static const bool has = __builtin_cpu_supports("avx512f") && __builtin_cpu_supports("avx512dq");
    return has;
#else
    return false;
#endif
}

}  // namespace

void remaindersDescendingScalar(const uint64_t* x, uint64_t top, uint32_t count, uint32_t* out) {
    for (uint32_t k = 0; k < count; ++k) {
        const uint64_t n = top - k;
        out[k] = uint32_t(remainderByDigits(x[k], n, 1.0 / double(n)));
    }
}

void remaindersDescending(const uint64_t* x, uint64_t top, uint32_t count, uint32_t* out) {
#if defined(__x86_64__) || defined(_M_X64)
    if (hasAvx512dq()) return remaindersDescendingAvx512(x, top, count, out);
#endif
    remaindersDescendingScalar(x, top, count, out);
}

void drawBelowDescending(SplitMix64& rng, uint64_t top, uint32_t count, uint32_t* out) {
#if defined(__x86_64__) || defined(_M_X64)
    if (hasAvx512dq()) return drawBelowDescendingAvx512(rng, top, count, out);
#endif
    uint64_t x[64];
    for (uint32_t first = 0; first < count; first += 64) {
        const uint32_t n = count - first < 64 ? count - first : 64;
        for (uint32_t k = 0; k < n; ++k) x[k] = rng.next();
        remaindersDescending(x, top - first, n, out + first);
    }
}

}  // namespace nrad
