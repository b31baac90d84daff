// AVX2 + FMA kernel: 8 points per vector, weights broadcast. Compiled with -mavx2 -mfma; called only
// after the CPU was checked.
#include <immintrin.h>

#include "kernels.h"

namespace nrad::rt {

// Scale, output transform and clamp of the three outputs of lanes [p, p + 8), stored to y.
static inline void storeRadiance(const NetworkView& net, const __m256 a[3], float* y, int p) {
    const __m256 zero = _mm256_setzero_ps();
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

// The default topology, 9-9-3, with every size known at compile time: inputs, hidden units and outputs
// stay in registers, and each hidden unit feeds the outputs as soon as it is computed.
static void evalDefaultTopology(const NetworkView& net, const float* x, float* y) {
    const float* W1 = net.params;
    const float* b1 = W1 + 9 * 9;
    const float* W2 = b1 + 9;
    const float* b2 = W2 + 3 * 9;
    const __m256 zero = _mm256_setzero_ps();
    for (int p = 0; p < kChunk; p += 8) {
        __m256 in[9];
        for (int i = 0; i < 9; ++i) in[i] = _mm256_loadu_ps(x + i * kChunk + p);
        __m256 out[3] = {_mm256_set1_ps(b2[0]), _mm256_set1_ps(b2[1]), _mm256_set1_ps(b2[2])};
        for (int j = 0; j < 9; ++j) {
            __m256 h = _mm256_set1_ps(b1[j]);
            for (int i = 0; i < 9; ++i) h = _mm256_fmadd_ps(_mm256_set1_ps(W1[j * 9 + i]), in[i], h);
            h = _mm256_max_ps(h, zero);
            for (int c = 0; c < 3; ++c) out[c] = _mm256_fmadd_ps(_mm256_set1_ps(W2[c * 9 + j]), h, out[c]);
        }
        storeRadiance(net, out, y, p);
    }
}

void evalChunkAvx2(const NetworkView& net, const float* x, float* y) {
    if (net.hiddenLayers == 1 && net.hiddenWidths[0] == 9) return evalDefaultTopology(net, x, y);
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
        storeRadiance(net, a, y, p);
    }
}

}  // namespace nrad::rt
