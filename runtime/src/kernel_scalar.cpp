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
        for (int c = 0; c < kOutputs; ++c) y[c * kChunk + p] = a[c];
    }
}

}  // namespace nrad::rt
