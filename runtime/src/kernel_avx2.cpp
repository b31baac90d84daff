// AVX2 + FMA kernel: 8 points per vector, weights broadcast. Compiled with -mavx2 -mfma; called only
// after the CPU was checked.
#include <immintrin.h>

#include "kernels.h"

namespace nrad::rt {

void evalChunkAvx2(const NetworkView& net, const float* x, float* y) {
    __m256 a[kMaxWidth], b[kMaxWidth];
    const __m256 zero = _mm256_setzero_ps();
    for (int p = 0; p < kChunk; p += 8) {
        int in = kInputs;
        for (int i = 0; i < kInputs; ++i) a[i] = _mm256_loadu_ps(x + i * kChunk + p);
        const float* w = net.params;
        for (uint32_t l = 0; l <= net.hiddenLayers; ++l) {
            bool last = l == net.hiddenLayers;
            int out = last ? kOutputs : int(net.hiddenWidths[l]);
            const float* bias = w + out * in;
            for (int o = 0; o < out; ++o) {
                __m256 s = _mm256_set1_ps(bias[o]);
                const float* row = w + o * in;
                for (int i = 0; i < in; ++i) s = _mm256_fmadd_ps(_mm256_set1_ps(row[i]), a[i], s);
                b[o] = last ? s : _mm256_max_ps(s, zero);
            }
            for (int o = 0; o < out; ++o) a[o] = b[o];
            w = bias + out;
            in = out;
        }
        const __m256 scale = _mm256_set1_ps(net.scale);
        for (int c = 0; c < kOutputs; ++c) {
            __m256 v = a[c];
            if (net.exponential) {
                __m256 xe = _mm256_min_ps(_mm256_max_ps(v, _mm256_set1_ps(kExpLo)), _mm256_set1_ps(kExpHi));
                __m256 n = _mm256_round_ps(_mm256_mul_ps(xe, _mm256_set1_ps(kLog2e)), _MM_FROUND_TO_NEAREST_INT | _MM_FROUND_NO_EXC);
                __m256 r = _mm256_fnmadd_ps(n, _mm256_set1_ps(kLn2Lo), _mm256_fnmadd_ps(n, _mm256_set1_ps(kLn2Hi), xe));
                __m256 q = _mm256_set1_ps(kExpP[6]);
                for (int k = 5; k >= 0; --k) q = _mm256_fmadd_ps(q, r, _mm256_set1_ps(kExpP[k]));
                __m256i e = _mm256_slli_epi32(_mm256_add_epi32(_mm256_cvtps_epi32(n), _mm256_set1_epi32(127)), 23);
                v = _mm256_sub_ps(_mm256_mul_ps(q, _mm256_castsi256_ps(e)), _mm256_set1_ps(1.0f));
            }
            // max(v * scale, 0) with the zero first: a NaN in v yields 0.
            _mm256_storeu_ps(y + c * kChunk + p, _mm256_max_ps(_mm256_mul_ps(v, scale), zero));
        }
    }
}

}  // namespace nrad::rt
