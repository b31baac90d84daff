// The machine's FMA peak, measured (benchmarks report throughput as a fraction of it, taken in the same run).
// x86-64 only: kChains independent chains of AVX-512 or AVX2 FMAs on `threads` threads.
#pragma once

#if defined(__x86_64__)
#include <algorithm>
#include <chrono>
#include <thread>
#include <vector>

#include <immintrin.h>

namespace fma_peak {

using clock_type = std::chrono::steady_clock;

// kChains independent chains of FMAs: enough to cover the FMA latency on two pipes, few enough that
// the chains and the two constants stay in registers (16 with AVX2, 32 with AVX-512).
constexpr int kChains = 12;

__attribute__((target("avx512f"))) inline double fmaLoop512(long iters) {
    __m512 acc[kChains];
    for (int i = 0; i < kChains; ++i) acc[i] = _mm512_set1_ps(float(i));
    const __m512 a = _mm512_set1_ps(0.999999f), b = _mm512_set1_ps(1e-7f);
    for (long it = 0; it < iters; ++it)
        for (int i = 0; i < kChains; ++i) acc[i] = _mm512_fmadd_ps(acc[i], a, b);
    float sum = 0.0f, out[16];
    for (int i = 0; i < kChains; ++i) {
        _mm512_storeu_ps(out, acc[i]);
        sum += out[0];
    }
    return double(sum);
}
__attribute__((target("avx2,fma"))) inline double fmaLoop256(long iters) {
    __m256 acc[kChains];
    for (int i = 0; i < kChains; ++i) acc[i] = _mm256_set1_ps(float(i));
    const __m256 a = _mm256_set1_ps(0.999999f), b = _mm256_set1_ps(1e-7f);
    for (long it = 0; it < iters; ++it)
        for (int i = 0; i < kChains; ++i) acc[i] = _mm256_fmadd_ps(acc[i], a, b);
    float sum = 0.0f, out[8];
    for (int i = 0; i < kChains; ++i) {
        _mm256_storeu_ps(out, acc[i]);
        sum += out[0];
    }
    return double(sum);
}

inline volatile double gSink = 0.0;

// FMA lanes per second (one lane-FMA = one multiply-add) on `threads` threads with `width`-wide vectors
// (16: AVX-512, 8: AVX2).
inline double fmaPeak(int threads, int width) {
    const long iters = 20'000'000;
    double best = 0.0;
    for (int rep = 0; rep < 3; ++rep) {
        auto t0 = clock_type::now();
        std::vector<std::thread> pool;
        for (int t = 0; t < threads; ++t)
            pool.emplace_back([&] {
                double s = width == 16 ? fmaLoop512(iters) : fmaLoop256(iters);
                gSink = gSink + s;
            });
        for (auto& t : pool) t.join();
        double dt = std::chrono::duration<double>(clock_type::now() - t0).count();
        best = std::max(best, double(iters) * kChains * width * threads / dt);
    }
    return best;
}

// Widest vector width this CPU runs (16: AVX-512, 8: AVX2 with FMA, 0: neither).
inline int widestFmaWidth() {
    __builtin_cpu_init();
    if (__builtin_cpu_supports("avx512f")) return 16;
    if (__builtin_cpu_supports("avx2") && __builtin_cpu_supports("fma")) return 8;
    return 0;
}

}  // namespace fma_peak
#endif
