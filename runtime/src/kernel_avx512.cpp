// AVX-512F kernel: 16 points per vector. Compiled with -mavx512f; called only after the CPU was checked.
// GCC 12's AVX-512 intrinsics pass _mm512_undefined_ps() as the masked-off source, which its
// -Wmaybe-uninitialized / -Wuninitialized report as a use of an uninitialised value (a false positive).
#pragma GCC diagnostic ignored "-Wmaybe-uninitialized"
#pragma GCC diagnostic ignored "-Wuninitialized"
#include <immintrin.h>

#include "kernels.h"

namespace nrad::rt {

// Scale, output transform and clamp of the three outputs of lanes [p, p + 16), stored to y.
static inline void storeRadiance(const NetworkView& net, const __m512 a[3], float* y, int p) {
    const __m512 zero = _mm512_setzero_ps();
    const __m512 scale = _mm512_set1_ps(net.scale);
    for (int c = 0; c < kOutputs; ++c) {
        __m512 v = a[c];
        if (net.exponential) {
            __m512 xe = _mm512_min_ps(_mm512_max_ps(v, _mm512_set1_ps(kExpLo)), _mm512_set1_ps(kExpHi));
            __m512 n = _mm512_roundscale_ps(_mm512_mul_ps(xe, _mm512_set1_ps(kLog2e)), _MM_FROUND_TO_NEAREST_INT | _MM_FROUND_NO_EXC);
            __m512 r = _mm512_fnmadd_ps(n, _mm512_set1_ps(kLn2Lo), _mm512_fnmadd_ps(n, _mm512_set1_ps(kLn2Hi), xe));
            __m512 q = _mm512_set1_ps(kExpP[6]);
            for (int k = 5; k >= 0; --k) q = _mm512_fmadd_ps(q, r, _mm512_set1_ps(kExpP[k]));
            __m512i e = _mm512_slli_epi32(_mm512_add_epi32(_mm512_cvtps_epi32(n), _mm512_set1_epi32(127)), 23);
            v = _mm512_sub_ps(_mm512_mul_ps(q, _mm512_castsi512_ps(e)), _mm512_set1_ps(1.0f));
        }
        // max(v * scale, 0) with the zero first: a NaN in v yields 0.
        _mm512_storeu_ps(y + c * kChunk + p, _mm512_max_ps(_mm512_mul_ps(v, scale), zero));
    }
}

// The default topology, 9-9-3, with every size known at compile time: inputs, hidden units and outputs
// stay in registers, and each hidden unit feeds the outputs as soon as it is computed.
static void evalDefaultTopology(const NetworkView& net, const float* x, float* y) {
    const float* W1 = net.params;
    const float* b1 = W1 + 9 * 9;
    const float* W2 = b1 + 9;
    const float* b2 = W2 + 3 * 9;
    const __m512 zero = _mm512_setzero_ps();
    for (int p = 0; p < kChunk; p += 16) {
        __m512 in[9];
        for (int i = 0; i < 9; ++i) in[i] = _mm512_loadu_ps(x + i * kChunk + p);
        __m512 out[3] = {_mm512_set1_ps(b2[0]), _mm512_set1_ps(b2[1]), _mm512_set1_ps(b2[2])};
        for (int j = 0; j < 9; ++j) {
            __m512 h = _mm512_set1_ps(b1[j]);
            for (int i = 0; i < 9; ++i) h = _mm512_fmadd_ps(_mm512_set1_ps(W1[j * 9 + i]), in[i], h);
            h = _mm512_max_ps(h, zero);
            for (int c = 0; c < 3; ++c) out[c] = _mm512_fmadd_ps(_mm512_set1_ps(W2[c * 9 + j]), h, out[c]);
        }
        storeRadiance(net, out, y, p);
    }
}

void evalChunkAvx512(const NetworkView& net, const float* x, float* y) {
    if (net.hiddenLayers == 1 && net.hiddenWidths[0] == 9) return evalDefaultTopology(net, x, y);
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
                b[o] = last ? s : _mm512_max_ps(s, zero);
            }
            for (int o = 0; o < out; ++o) a[o] = b[o];
            w = bias + out;
            in = out;
        }
        storeRadiance(net, a, y, p);
    }
}

}  // namespace nrad::rt
