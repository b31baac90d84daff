// The baseline engines use today: a grid of L2 spherical-harmonics radiance probes (9 coefficients per
// colour channel), trilinearly interpolated and evaluated in the outgoing direction. Fitted by least
// squares to the same training samples the networks learn from, with as many probes as fit in the bytes
// the networks take (coefficients stored as fp16, like the networks' weights).
#pragma once

#include <cstddef>
#include <functional>
#include <string>
#include <vector>

#include <glm/glm.hpp>

#include "baker/bake/training_samples.h"

namespace nrad {

// The nine real L2 SH basis functions at unit direction d (the usual order: l = 0; l = 1: y, z, x; l = 2).
void shBasis(const glm::vec3& d, float y[9]);

struct ShProbeGrid {
    glm::uvec3 dims{2, 2, 2};  // probes per axis, at least 2: probes sit on a regular lattice over [lower, upper]
    glm::vec3 lower{0.0f}, upper{1.0f};
    std::vector<float> coeffs;  // per probe (x fastest): 27 floats, channel-major (9 for R, 9 for G, 9 for B)

    size_t probeCount() const { return size_t(dims.x) * dims.y * dims.z; }
    size_t bytes() const { return probeCount() * 27 * 2; }  // as fp16
    // Radiance leaving p towards wo (clamped at 0); p is clamped into the grid's box.
    glm::vec3 evaluate(const glm::vec3& p, const glm::vec3& wo) const;
};

// The largest probe lattice over `lower`..`upper` whose fp16 coefficients fit in `byteBudget` bytes, with
// its spacing as even as the box allows (at least 2 probes per axis).
glm::uvec3 probeDimsForBudget(const glm::vec3& lower, const glm::vec3& upper, size_t byteBudget);

struct ShFitStats {
    int iterations = 0;  // conjugate-gradient iterations (largest of the three channels)
    double relativeResidual = 0.0;  // |A^T(b - A x)| / |A^T b| at the end, largest channel
    double trainRelMse = 0.0;  // relMSE of the fitted grid on the samples
};

// Least squares: minimise sum_s |L_grid(x_s, wo_s) - L_s|^2 + ridge * trace(A^T A) / K * |c|^2 by conjugate
// gradients on the normal equations (K unknowns per channel, the three channels side by side), preconditioned
// by each probe's 9 x 9 block of them (block Jacobi); the ridge keeps probes that no sample reaches at zero.
// A channel stops at a relative residual of 1e-7, or once the objective falls by less than 1e-2 of itself
// over 10 iterations (sh_probes.cpp: what that leaves is invisible in the image). Coefficients are then
// rounded to fp16. Runs in parallel (TBB), every sum in a fixed order: the same bytes whatever the number of
// threads and whichever kernel. `progress` gets the fraction done (the slowest channel's way to its stop,
// log scale), rising. `kernel`: one of shFitKernels(), or empty for the first (std::invalid_argument if the
// CPU has no such kernel).
ShProbeGrid fitShProbeGrid(const std::vector<TrainingSample>& samples, const glm::vec3& lower, const glm::vec3& upper,
                           const glm::uvec3& dims, ShFitStats* stats = nullptr, double ridge = 1e-4,
                           const std::function<void(double)>& progress = {}, const std::string& kernel = {});

// The fit's kernels on this CPU, widest first ("avx512", "avx2", then "plain", which every CPU has): the same
// code compiled for each ISA.
std::vector<std::string> shFitKernels();

}  // namespace nrad
