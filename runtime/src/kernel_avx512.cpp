// AVX-512F kernel: 16 points per vector. Compiled with -mavx512f; called only after the CPU was checked.
#include <immintrin.h>

#include "kernels.h"

namespace nrad::rt {

void evalChunkAvx512(const NetworkView& net, const float* x, float* y) {
    __m512 a[kMaxWidth], b[kMaxWidth];
    const __m512 zero = _mm512_setzero_ps();
    for (int p = 0; p < kChunk; p += 16) {
        int in = kInputs;
        for (int i = 0; i < kInputs; ++i) a[i] = _mm512_loadu_ps(x + i * kChunk + p);
        const float* w = net.params;
        for (uint32_t l = 0; l <= net.hiddenLayers; ++l) {
            bool last = l == net.hiddenLayers;
            int out = last ? kOutputs : int(net.hiddenWidths[l]);
            const float* bias = w + out * in;
            for (int o = 0; o < out; ++o) {
                __m512 s = _mm512_set1_ps(bias[o]);
                const float* row = w + o * in;
                for (int i = 0; i < in; ++i) s = _mm512_fmadd_ps(_mm512_set1_ps(row[i]), a[i], s);
                // The zero-masking form: GCC 12 warns about the undefined pass-through of _mm512_max_ps.
                b[o] = last ? s : _mm512_maskz_max_ps(__mmask16(0xFFFF), s, zero);
            }
            for (int o = 0; o < out; ++o) a[o] = b[o];
            w = bias + out;
            in = out;
        }
        for (int c = 0; c < kOutputs; ++c) _mm512_storeu_ps(y + c * kChunk + p, a[c]);
    }
}

}  // namespace nrad::rt
