// The evaluation contract of an .nrad asset, defined once: how a point finds its network, how the nine
// inputs are encoded, how a network's outputs become radiance, and how that radiance is recombined with the
// surface's material when shading. The baker (training targets, inputs, the decoded prediction it judges)
// and the runtime's scalar path call these functions; the SIMD kernels compute the same arithmetic in
// vector registers and are tested against vectors generated from here (tests/runtime). docs/format.md
// specifies it in words. Only the C++17 standard library.
#pragma once

#include <cmath>
#include <cstdint>
#include <cstring>

#include "nrad/eval_constants.h"
#include "nrad/format.h"

namespace nrad::eval {

// ----- how a point finds its network -----------------------------------------------------------------------

// dims / (upper - lower) along one axis: the factor of the continuous grid coordinate (computed once per
// grid; every user multiplies by this very float, so the voxel rule and the position input always agree).
inline float gridFactor(const format::Grid& g, int axis) { return float(g.dims[axis]) / (g.upper[axis] - g.lower[axis]); }

// Continuous grid coordinate of p along one axis: (p - lower) x factor.
inline float gridCoordinate(float p, float lower, float factor) { return (p - lower) * factor; }

// Voxel coordinate from the continuous one: floor(t), with the upper face belonging to the last voxel. A point
// on an interior border belongs to the voxel above it.
inline int voxelCoordinate(float t, uint32_t dim) {
    int i = int(t);
    return i >= int(dim) ? int(dim) - 1 : (i < 0 ? 0 : i);
}

// Where a point is: its voxel (linear index x + dims[0] (y + dims[1] z)) and its position inside that voxel
// mapped to [-1, 1]^3 (the network's first three inputs: 2 (t - coord) - 1, clamped to [-1, 1]).
struct Location {
    int64_t voxel = -1;  // -1: outside the grid [lower, upper] (or not finite)
    int coord[3] = {0, 0, 0};
    float local[3] = {0, 0, 0};
};

// Position of p relative to voxel `coord`, in the voxel's [-1, 1]^3 frame (not clamped: beyond +-1 outside
// that voxel).
inline float localCoordinate(float p, float lower, float factor, int coord) {
    return 2.0f * (gridCoordinate(p, lower, factor) - float(coord)) - 1.0f;
}

inline float clampUnit(float q) { return q < -1.0f ? -1.0f : (q > 1.0f ? 1.0f : q); }

// `factor` holds gridFactor for the three axes.
inline Location locate(const format::Grid& g, const float factor[3], const float p[3]) {
    Location r;
    for (int k = 0; k < 3; ++k) {
        if (!(p[k] >= g.lower[k] && p[k] <= g.upper[k])) return r;
        r.coord[k] = voxelCoordinate(gridCoordinate(p[k], g.lower[k], factor[k]), g.dims[k]);
        r.local[k] = clampUnit(localCoordinate(p[k], g.lower[k], factor[k], r.coord[k]));
    }
    r.voxel = int64_t(r.coord[0]) + int64_t(g.dims[0]) * (int64_t(r.coord[1]) + int64_t(g.dims[1]) * int64_t(r.coord[2]));
    return r;
}

inline Location locate(const format::Grid& g, const float p[3]) {
    const float factor[3] = {gridFactor(g, 0), gridFactor(g, 1), gridFactor(g, 2)};
    return locate(g, factor, p);
}

// ----- inputs ------------------------------------------------------------------------------------------------

// x = (position in the voxel, shading normal, direction towards the viewer), normal and direction unit
// length in world space.
inline void encodeInputs(const float local[3], const float normal[3], const float direction[3], float x[kInputs]) {
    for (int k = 0; k < 3; ++k) {
        x[k] = local[k];
        x[3 + k] = normal[k];
        x[6 + k] = direction[k];
    }
}

// ----- the network --------------------------------------------------------------------------------------------

// The plain forward pass of one network in the format's parameter order (per layer W, out x in row-major,
// then b): ReLU hidden layers, a linear last layer, in float, each sum from the bias up in input order.
constexpr uint32_t kForwardScratch = 2 * format::kMaxHiddenWidth;  // floats of scratch forward() needs
inline void forward(uint32_t hiddenLayers, const uint32_t* hiddenWidths, const float* params, const float x[kInputs],
                    float y[kOutputs], float* scratch) {
    float* a = scratch;
    float* b = scratch + format::kMaxHiddenWidth;
    uint32_t in = uint32_t(kInputs);
    for (int i = 0; i < kInputs; ++i) a[i] = x[i];
    const float* w = params;
    for (uint32_t l = 0; l <= hiddenLayers; ++l) {
        bool last = l == hiddenLayers;
        uint32_t out = last ? uint32_t(kOutputs) : hiddenWidths[l];
        const float* bias = w + size_t(out) * in;
        for (uint32_t o = 0; o < out; ++o) {
            float s = bias[o];
            for (uint32_t i = 0; i < in; ++i) s += w[size_t(o) * in + i] * a[i];
            b[o] = last || s > 0.0f ? s : 0.0f;
        }
        for (uint32_t o = 0; o < out; ++o) a[o] = b[o];
        w = bias + out;
        in = out;
    }
    for (int c = 0; c < kOutputs; ++c) y[c] = a[c];
}

inline void forward(const format::Topology& t, const float* params, const float x[kInputs], float y[kOutputs], float* scratch) {
    forward(uint32_t(t.hiddenWidths.size()), t.hiddenWidths.data(), params, x, y, scratch);
}

// ----- outputs --------------------------------------------------------------------------------------------------

// exp(y) - 1 (constants in nrad/eval_constants.h). The SIMD kernels compute the same steps (and the layers)
// with fused multiply-adds, their own order of sums and round-to-nearest-even for n, which changes the last
// bits (tests/runtime holds them to 1e-5 of max(1, value) against this file).
inline float expMinusOne(float v) {
    float xe = v < kMinLog ? kMinLog : (v > kMaxLog ? kMaxLog : v);  // NaN stays NaN (mapped to 0 below)
    float n = float(int(xe * kLog2e + (xe >= 0.0f ? 0.5f : -0.5f)));
    float r = (xe - n * kLn2Hi) - n * kLn2Lo;
    float q = kExpP[6];
    for (int k = 5; k >= 0; --k) q = q * r + kExpP[k];
    int bits = (int(n) + 127) << 23;  // 2^n from its exponent bits
    float pow2;
    std::memcpy(&pow2, &bits, 4);
    return q * pow2 - 1.0f;
}

// Radiance from one output value: transform, the voxel's scale, clamped at 0 (NaN becomes 0).
inline float decodeOutput(format::OutputTransform transform, float scale, float y) {
    float v = transform == format::OutputTransform::Exponential ? expMinusOne(y) : y;
    v *= scale;
    return v > 0.0f ? v : 0.0f;
}

inline void decodeOutputs(format::OutputTransform transform, float scale, const float y[kOutputs], float rgb[kOutputs]) {
    for (int c = 0; c < kOutputs; ++c) rgb[c] = decodeOutput(transform, scale, y[c]);
}

// ----- shading: what the networks store, and how it is recombined with the material ------------------------------

// The radiance leaving a surface point towards the viewer, from what the asset returns there and the
// surface's own emission towards the viewer (its material's emissive term, textures included): an asset
// with format::kFlagScatteredRadiance stores L - Le, so Le is added back; an asset without it stores L.
inline void shade(uint32_t contentFlags, const float assetRadiance[3], const float emission[3], float out[3]) {
    const bool scattered = (contentFlags & format::kFlagScatteredRadiance) != 0;
    for (int c = 0; c < 3; ++c) out[c] = assetRadiance[c] + (scattered ? emission[c] : 0.0f);
}

}  // namespace nrad::eval
