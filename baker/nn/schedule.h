// Learning-rate schedules of the baker's networks.
#pragma once

#include <cmath>

namespace nrad {

// Exponential decay from `start` at t = 0 to start x finalFactor at t = 1 (the voxel networks: to a tenth over
// their epochs; integral training: between its first and last round's rates).
inline float exponentialDecay(float start, float finalFactor, float t) { return start * std::pow(finalFactor, t); }

// Linear decay from `start` at t = 0 to zero at t = 1 (the light selector's warm-up, so that the weights it
// freezes are not one noisy step's).
inline float linearDecay(float start, float t) { return start * (t < 1.0f ? 1.0f - t : 0.0f); }

}  // namespace nrad
