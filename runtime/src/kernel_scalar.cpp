// The reference kernel: one point at a time, in the order of the format's definition.
#include "kernels.h"

namespace nrad::rt {

void evalChunkScalar(const NetworkView& net, const float* x, float* y) {
    float a[kMaxWidth], b[kMaxWidth];
    for (int p = 0; p < kChunk; ++p) {
        int in = kInputs;
        for (int i = 0; i < kInputs; ++i) a[i] = x[i * kChunk + p];
        const float* w = net.params;
        for (uint32_t l = 0; l <= net.hiddenLayers; ++l) {
            bool last = l == net.hiddenLayers;
            int out = last ? kOutputs : int(net.hiddenWidths[l]);
            const float* bias = w + out * in;
            for (int o = 0; o < out; ++o) {
                float s = bias[o];
                for (int i = 0; i < in; ++i) s += w[o * in + i] * a[i];
                b[o] = last || s > 0.0f ? s : 0.0f;
            }
            for (int o = 0; o < out; ++o) a[o] = b[o];
            w = bias + out;
            in = out;
        }
        for (int c = 0; c < kOutputs; ++c) {
            float v = a[c];
            if (net.exponential) {
                float xe = v < kExpLo ? kExpLo : (v > kExpHi ? kExpHi : v);
                float n = float(int(xe * kLog2e + (xe >= 0.0f ? 0.5f : -0.5f)));
                float r = (xe - n * kLn2Hi) - n * kLn2Lo;
                float q = kExpP[6];
                for (int k = 5; k >= 0; --k) q = q * r + kExpP[k];
                // q x 2^n by building the exponent bits.
                int bits = (int(n) + 127) << 23;
                float pow2;
                __builtin_memcpy(&pow2, &bits, 4);
                v = q * pow2 - 1.0f;
            }
            v *= net.scale;
            y[c * kChunk + p] = v > 0.0f ? v : 0.0f;  // NaN compares false: 0
        }
    }
}

}  // namespace nrad::rt
