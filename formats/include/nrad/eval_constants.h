// Constants of the evaluation contract (nrad/eval.h) that the SIMD kernels need too. Values only, no
// functions: the runtime's SIMD translation units (compiled for AVX2 / AVX-512) include it without sharing
// any inline code with the rest of the program.
#pragma once

namespace nrad::eval {

constexpr int kInputs = 9;  // position in the voxel (3), shading normal (3), direction towards the viewer (3)
constexpr int kOutputs = 3;  // RGB

// The exponential output transform is exp(y) - 1 with y clamped to [kMinLog, kMaxLog], exp by range reduction
// y = n ln2 + r and a degree-6 polynomial on |r| <= ln2 / 2 (relative error below 2e-7). The same constants
// and the same order of operations in every kernel.
constexpr float kMinLog = -87.0f, kMaxLog = 80.0f;
constexpr float kLog2e = 1.44269504f, kLn2Hi = 0.693359375f, kLn2Lo = -2.12194440e-4f;
// Every decoded network output is clamped to [0, kMaxRadiance] (NaN becomes 0): whatever weights, scales and
// finite inputs an accepted asset meets, its radiance stays finite, blended (weights sum to 1) or shaded
// (docs/format.md, "Output transform"). Far above any radiance a scene holds, in any units.
constexpr float kMaxRadiance = 1e30f;
constexpr float kExpP[7] = {1.0f, 1.0f, 0.5f, 0.166666672f, 0.0416666567f, 0.00833336264f, 0.00138889090f};
// 2^x (exp2Poly, the reflectance fit's) by x = n + f, 2^f = exp(f ln2) on the polynomial above: x clamped to
// [-kMaxExp2, kMaxExp2], where 2^x stays a normal float.
constexpr float kLn2 = 0.693147181f, kMaxExp2 = 125.0f;

}  // namespace nrad::eval
