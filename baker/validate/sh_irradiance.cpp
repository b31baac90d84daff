// L2 SH irradiance probes: placement, fit from the tracer's receivers, and evaluation with the leak guards.
#include "baker/validate/sh_irradiance.h"

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <nrad/format.h>

#include "baker/bake/volume_samples.h"
#include "baker/nn/random.h"
#include "baker/util/maths.h"
#include "baker/validate/sh_probes.h"

namespace nrad {

namespace {

// n directions spread evenly over the sphere (a Fibonacci lattice), turned by the rotation `r`.
void fibonacciSphere(uint32_t n, const glm::mat3& r, std::vector<glm::vec3>& out) {
    out.resize(n);
    const float golden = kPi * (3.0f - std::sqrt(5.0f));
    for (uint32_t i = 0; i < n; ++i) {
        const float z = 1.0f - (2.0f * float(i) + 1.0f) / float(n);
        const float s = std::sqrt(std::max(0.0f, 1.0f - z * z)), phi = golden * float(i);
        out[i] = r * glm::vec3(s * std::cos(phi), s * std::sin(phi), z);
    }
}

// A uniformly random rotation (from a random unit quaternion).
glm::mat3 randomRotation(SplitMix64& g) {
    const float u1 = g.uniform(), u2 = 2.0f * kPi * g.uniform(), u3 = 2.0f * kPi * g.uniform();
    const float a = std::sqrt(1.0f - u1), b = std::sqrt(u1);
    const float x = a * std::sin(u2), y = a * std::cos(u2), z = b * std::sin(u3), w = b * std::cos(u3);
    return glm::mat3(1 - 2 * (y * y + z * z), 2 * (x * y + z * w), 2 * (x * z - y * w),  // column 0
                     2 * (x * y - z * w), 1 - 2 * (x * x + z * z), 2 * (y * z + x * w),  // column 1
                     2 * (x * z + y * w), 2 * (y * z - x * w), 1 - 2 * (x * x + y * y));  // column 2
}

// Solves the 9 x 9 symmetric positive definite system m x = b (Cholesky) in place of b; false if it is not so.
bool solveSpd9(double m[9][9], double b[3][9]) {
    for (int i = 0; i < 9; ++i)
        for (int k = 0; k <= i; ++k) {
            double s = m[i][k];
            for (int j = 0; j < k; ++j) s -= m[i][j] * m[k][j];
            if (i == k) {
                if (!(s > 0.0)) return false;
                m[i][i] = std::sqrt(s);
            } else {
                m[i][k] = s / m[k][k];
            }
        }
    for (int c = 0; c < 3; ++c) {
        for (int i = 0; i < 9; ++i) {
            double s = b[c][i];
            for (int j = 0; j < i; ++j) s -= m[i][j] * b[c][j];
            b[c][i] = s / m[i][i];
        }
        for (int i = 8; i >= 0; --i) {
            double s = b[c][i];
            for (int j = i + 1; j < 9; ++j) s -= m[j][i] * b[c][j];
            b[c][i] = s / m[i][i];
        }
    }
    return true;
}

}  // namespace

glm::vec3 ShIrradianceGrid::probePosition(size_t i) const {
    const glm::uvec3 c(uint32_t(i % dims.x), uint32_t((i / dims.x) % dims.y), uint32_t(i / (size_t(dims.x) * dims.y)));
    return lower + (upper - lower) * (glm::vec3(c) + 0.5f) / glm::vec3(dims);
}

glm::vec3 ShIrradianceGrid::evaluate(const glm::vec3& p, const glm::vec3& n) const {
    int c[3];
    float f[3];
    for (int k = 0; k < 3; ++k) {
        float t = (p[k] - lower[k]) / (upper[k] - lower[k]) * float(dims[k]) - 0.5f;
        t = std::isfinite(t) ? std::min(std::max(t, 0.0f), float(dims[k] - 1)) : 0.0f;
        c[k] = std::min(int(t), std::max(0, int(dims[k]) - 2));
        f[k] = dims[k] > 1 ? t - float(c[k]) : 0.0f;
    }
    float y[9];
    shBasis(n, y);
    glm::vec3 sum(0.0f);
    float total = 0.0f;
    for (int corner = 0; corner < 8; ++corner) {
        const int d[3] = {corner & 1, (corner >> 1) & 1, corner >> 2};
        float w = 1.0f;
        size_t index = 0, stride = 1;
        bool inside = true;
        for (int k = 0; k < 3; ++k) {
            if (d[k] && uint32_t(c[k] + 1) >= dims[k]) inside = false;
            w *= d[k] ? f[k] : 1.0f - f[k];
            index += size_t(c[k] + d[k]) * stride;
            stride *= dims[k];
        }
        if (!inside || w <= 0.0f || !valid[index]) continue;
        // DDGI's smooth back-face weight: a probe behind the receiver's surface counts little.
        const glm::vec3 to = probePosition(index) - p;
        const float len = glm::length(to);
        const float facing = len > 0.0f ? 0.5f * (glm::dot(to / len, n) + 1.0f) : 1.0f;
        w *= facing * facing + 0.2f;
        const float* co = &coeffs[index * 27];
        glm::vec3 v(0.0f);
        for (int ch = 0; ch < 3; ++ch)
            for (int i = 0; i < 9; ++i) v[ch] += co[ch * 9 + i] * y[i];
        sum += w * v;
        total += w;
    }
    if (!(total > 0.0f)) return glm::vec3(0.0f);
    return glm::max(sum / total, glm::vec3(0.0f));
}

glm::uvec3 irradianceDimsForBudget(const glm::vec3& lower, const glm::vec3& upper, size_t byteBudget) {
    const glm::vec3 extent = glm::max(upper - lower, glm::vec3(1e-6f));
    glm::uvec3 dims(1);
    auto bytes = [](const glm::uvec3& d) { const size_t n = size_t(d.x) * d.y * d.z; return n * 54 + (n + 7) / 8; };
    for (;;) {  // refine the axis with the widest spacing while the budget allows
        int axis = 0;
        for (int k = 1; k < 3; ++k)
            if (extent[k] / float(dims[k]) > extent[axis] / float(dims[axis])) axis = k;
        glm::uvec3 next = dims;
        ++next[axis];
        if (bytes(next) > byteBudget) break;
        dims = next;
    }
    return dims;
}

ShIrradianceGrid fitShIrradianceGrid(const PathTracer& tracer, const glm::vec3& lower, const glm::vec3& upper, const glm::uvec3& dims,
                                     const ShIrradianceFit& fit, ShIrradianceStats* stats, const std::function<void(double)>& progress) {
    const auto t0 = std::chrono::steady_clock::now();
    ShIrradianceGrid g;
    g.dims = glm::max(dims, glm::uvec3(1));
    g.lower = lower;
    g.upper = upper;
    const size_t count = g.probeCount();
    g.coeffs.assign(count * 27, 0.0f);
    g.valid.assign(count, 0);
    const uint32_t normals = std::max(9u, fit.normalsPerProbe), paths = std::max(1u, fit.pathsPerNormal);
    std::atomic<uint64_t> rays{0}, leftOut{0};
    std::atomic<size_t> done{0};
    tbb::parallel_for(tbb::blocked_range<size_t>(0, count, 1), [&](const tbb::blocked_range<size_t>& range) {
        RayCounters counters;
        std::vector<glm::vec3> dirs;
        std::vector<SurfaceInteraction> starts;
        std::vector<PathStart> batch;
        std::vector<glm::vec3> estimates;
        for (size_t i = range.begin(); i != range.end(); ++i) {
            const glm::vec3 p = g.probePosition(i);
            // Every probe from (seed, index) alone: the same whatever the threads.
            SplitMix64 r(SplitMix64(uint64_t(fit.seed) ^ 0x7368697272616400ull).next() + i);
            fibonacciSphere(fit.validityRays, randomRotation(r), dirs);
            uint32_t back = 0;
            for (const glm::vec3& d : dirs) back += tracer.viewable(receiverAt(p, d)) ? 0u : 1u;
            counters.extension += dirs.size();
            if (4 * back > fit.validityRays) {
                ++leftOut;
                ++done;
                continue;
            }
            fibonacciSphere(normals, randomRotation(r), dirs);
            starts.clear();
            for (const glm::vec3& d : dirs) starts.push_back(receiverAt(p, d));
            batch.clear();
            const uint32_t stream = uint32_t(SplitMix64(uint64_t(fit.seed) * 0x9e3779b97f4a7c15ull + i).next());
            for (uint32_t k = 0; k < normals; ++k)
                for (uint32_t j = 0; j < paths; ++j) batch.push_back({&starts[k], stream ^ (k * 0x85ebca6bu), j});
            estimates.resize(batch.size());
            tracer.estimate(batch.data(), batch.size(), fit.maxDepth, nullptr, 1, counters, estimates.data());
            // Least squares over the receivers: sum_k |c . Y(n_k) - D_k|^2.
            double m[9][9] = {}, b[3][9] = {};
            for (uint32_t k = 0; k < normals; ++k) {
                glm::dvec3 sum(0.0);
                uint32_t n = 0;
                for (uint32_t j = 0; j < paths; ++j) {
                    const glm::vec3& L = estimates[size_t(k) * paths + j];
                    if (!(std::isfinite(L.x) && std::isfinite(L.y) && std::isfinite(L.z))) continue;
                    sum += glm::dvec3(L);
                    ++n;
                }
                if (n == 0) continue;
                sum /= double(n);
                float y[9];
                shBasis(dirs[k], y);
                for (int a = 0; a < 9; ++a) {
                    for (int c = 0; c < 9; ++c) m[a][c] += double(y[a]) * y[c];
                    for (int ch = 0; ch < 3; ++ch) b[ch][a] += double(y[a]) * sum[ch];
                }
            }
            for (int a = 0; a < 9; ++a) m[a][a] += 1e-9 * double(normals);
            if (solveSpd9(m, b)) {
                g.valid[i] = 1;
                for (int ch = 0; ch < 3; ++ch)
                    for (int a = 0; a < 9; ++a) {
                        const float v = std::isfinite(b[ch][a]) ? float(b[ch][a]) : 0.0f;
                        g.coeffs[i * 27 + size_t(ch) * 9 + size_t(a)] = format::halfToFloat(format::floatToHalf(v));
                    }
            } else {
                ++leftOut;
            }
            const size_t d = ++done;
            if (progress && d % 64 == 0) progress(double(d) / double(count));
        }
        rays += counters.total();
    });
    if (stats) {
        stats->probes = count;
        stats->leftOut = leftOut;
        stats->paths = uint64_t(count - leftOut) * normals * paths;
        stats->rays = rays;
        stats->seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    }
    return g;
}

}  // namespace nrad
