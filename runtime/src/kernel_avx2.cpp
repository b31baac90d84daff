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
        for (int c = 0; c < kOutputs; ++c) _mm256_storeu_ps(y + c * kChunk + p, a[c]);
    }
}

}  // namespace nrad::rt
