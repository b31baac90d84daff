// The baseline engines use for what moves (issue 42): a grid of L2 spherical-harmonics irradiance probes, as in
// Unity's light probes and adaptive probe volumes, Godot's lightmap probes and DDGI's irradiance: per probe, 9
// coefficients per colour channel of D(n) = E(n) / pi (the radiance a white Lambertian receiver facing n
// scatters; an L2 irradiance is the L2 projection of the incident light convolved with the clamped cosine, so
// fitting D in the L2 basis of n is that probe). Stored as fp16. Evaluated with the leak guards engines add:
// probes inside closed solids are left out, and each of the 8 around a point is weighted by how far it lies in
// front of the receiver (DDGI's smooth back-face weight), the weights renormalised.
#pragma once

#include <cstddef>
#include <cstdint>
#include <functional>
#include <vector>

#include <glm/glm.hpp>

#include "baker/render/path_tracer.h"

namespace nrad {

struct ShIrradianceGrid {
    glm::uvec3 dims{1, 1, 1};  // probes per axis, at the centres of dims cells over [lower, upper]
    glm::vec3 lower{0.0f}, upper{1.0f};
    std::vector<float> coeffs;  // per probe (x fastest): 27 floats, channel-major, fp16 values
    std::vector<uint8_t> valid;  // per probe: 0 inside a closed solid (left out of every interpolation)

    size_t probeCount() const { return size_t(dims.x) * dims.y * dims.z; }
    // fp16 coefficients and one validity bit per probe.
    size_t bytes() const { return probeCount() * 27 * 2 + (probeCount() + 7) / 8; }
    glm::vec3 probePosition(size_t i) const;
    // D(p, n) = E(p, n) / pi from the probes around p (clamped at 0; 0 where every one is left out).
    glm::vec3 evaluate(const glm::vec3& p, const glm::vec3& n) const;
};

struct ShIrradianceFit {
    uint32_t normalsPerProbe = 128;  // receivers per probe, spread evenly over the sphere (Fibonacci, rotated)
    uint32_t pathsPerNormal = 8;  // tracer paths per receiver
    uint32_t validityRays = 32;  // a probe is left out where more than a quarter of these meet a back face
    uint32_t seed = 0;
    int maxDepth = 0;
};

struct ShIrradianceStats {
    uint64_t probes = 0, leftOut = 0, paths = 0, rays = 0;
    double seconds = 0.0;
};

// The probe grid over lower..upper for byteBudget: from one probe, a probe more along the axis of the widest
// spacing while bytes() stays within the budget (at least 1 probe per axis).
glm::uvec3 irradianceDimsForBudget(const glm::vec3& lower, const glm::vec3& upper, size_t byteBudget);

// Fits each probe by least squares to E / pi at its receivers, estimated by `tracer` (as the asset's volume is
// trained: configure the tracer likewise). In parallel; the same bytes for any number of threads.
ShIrradianceGrid fitShIrradianceGrid(const PathTracer& tracer, const glm::vec3& lower, const glm::vec3& upper, const glm::uvec3& dims,
                                     const ShIrradianceFit& fit, ShIrradianceStats* stats = nullptr,
                                     const std::function<void(double)>& progress = {});

}  // namespace nrad
