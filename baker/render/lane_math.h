// Helpers of the lanes kernels (bsdf_lanes.cpp, scatter_lanes.cpp): the standard library's functions written as
// the selects the compiler vectorises, with the same results as the functions they name.
#pragma once

#include <cfloat>
#include <cmath>

// The loops vectorise only with every helper inlined into them.
#if defined(__GNUC__)
#define NRAD_LANE inline __attribute__((always_inline))
#else
#define NRAD_LANE inline
#endif

namespace nrad::lanes {

NRAD_LANE float maxOf(float a, float b) { return a < b ? b : a; }  // std::max
NRAD_LANE float minOf(float a, float b) { return b < a ? b : a; }  // std::min
NRAD_LANE float clamp01(float v) { return v < 0.0f ? 0.0f : (1.0f < v ? 1.0f : v); }  // std::clamp(v, 0, 1)
NRAD_LANE bool finite(float x) { return std::abs(x) <= FLT_MAX; }  // std::isfinite

}  // namespace nrad::lanes
