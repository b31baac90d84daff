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
    float scale;  // the voxel's output scale
    bool exponential;  // output transform: scale (exp(y) - 1) instead of scale y; clamped at 0 either way
};

// exp(x) for x in [-87, 88] by range reduction x = n ln2 + r and a degree-6 polynomial on |r| <= ln2/2
// (relative error below 2e-7); the same coefficients in every kernel. Inputs are clamped to that range.
constexpr float kExpHi = 88.0f, kExpLo = -87.0f, kLog2e = 1.44269504f, kLn2Hi = 0.693359375f, kLn2Lo = -2.12194440e-4f;
constexpr float kExpP[7] = {1.0f, 1.0f, 0.5f, 0.166666672f, 0.0416666567f, 0.00833336264f, 0.00138889090f};

// x: kInputs rows of kChunk floats; y: kOutputs rows of kChunk floats: the radiance (scale and output
// transform applied, never negative, NaN mapped to 0).
using ChunkKernel = void (*)(const NetworkView& net, const float* x, float* y);

void evalChunkScalar(const NetworkView& net, const float* x, float* y);
#if defined(__x86_64__) || defined(_M_X64)
void evalChunkAvx2(const NetworkView& net, const float* x, float* y);
void evalChunkAvx512(const NetworkView& net, const float* x, float* y);
#endif

}  // namespace nrad::rt
