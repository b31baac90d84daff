// The reference kernel: one point at a time, exactly nrad/eval.h's forward pass and output transform.
#include <nrad/eval.h>

#include "kernels.h"

namespace nrad::rt {

void evalChunkScalar(const NetworkView& net, const float* x, float* y, int count) {
    float scratch[eval::kForwardScratch];
    const format::OutputTransform transform =
        net.exponential ? format::OutputTransform::Exponential : format::OutputTransform::ClampedLinear;
    for (int p = 0; p < count; ++p) {
        float in[kInputs], out[kOutputs];
        for (int i = 0; i < kInputs; ++i) in[i] = x[i * kChunk + p];
        eval::forward(net.hiddenLayers, net.hiddenWidths, net.params, in, out, scratch);
        for (int c = 0; c < kOutputs; ++c) y[c * kChunk + p] = eval::decodeOutput(transform, net.scale, out[c]);
    }
}

void halfToFloatScalar(const uint16_t* in, float* out, size_t n) {
    for (size_t i = 0; i < n; ++i) out[i] = format::halfToFloat(in[i]);
}

void floatToHalfScalar(const float* in, uint16_t* out, size_t n) {
    for (size_t i = 0; i < n; ++i) out[i] = format::floatToHalf(in[i]);
}

}  // namespace nrad::rt
