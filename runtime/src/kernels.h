// Evaluation kernels: one network applied to a chunk of points in structure-of-arrays layout. Kept free of
// standard-library templates so the SIMD translation units share no inline code with the scalar ones.
#pragma once

#include <cstddef>
#include <cstdint>

namespace nrad::rt {

constexpr int kChunk = 64;  // points per chunk; the kernels process all of it (padding lanes are zeros)
constexpr int kMaxWidth = 256;
constexpr int kInputs = 9;
constexpr int kOutputs = 3;

struct NetworkView {
    const float* params;  // per layer: W (out x in, row-major), b (out)
    uint32_t hiddenLayers;
    const uint32_t* hiddenWidths;
};

// x: kInputs rows of kChunk floats; y: kOutputs rows of kChunk floats (the last layer's raw values).
using ChunkKernel = void (*)(const NetworkView& net, const float* x, float* y);

void evalChunkScalar(const NetworkView& net, const float* x, float* y);
#if defined(__x86_64__) || defined(_M_X64)
void evalChunkAvx2(const NetworkView& net, const float* x, float* y);
void evalChunkAvx512(const NetworkView& net, const float* x, float* y);
#endif

}  // namespace nrad::rt
