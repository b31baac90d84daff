// L2 SH probe grid: basis, trilinear weights, least-squares fit by conjugate gradients (in parallel, with
// every sum in a fixed order: the same coefficients whatever the number of threads).
#include "baker/validate/sh_probes.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <stdexcept>
#include <string>
#include <utility>

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <nrad/format.h>

#include "baker/util/maths.h"

namespace nrad {

namespace {

// The lattice cell holding p (clamped into the grid: its lower corner, per axis) and p's fraction across it.
void locate(const ShProbeGrid& g, const glm::vec3& p, int c[3], float f[3]) {
    for (int k = 0; k < 3; ++k) {
        float t = (p[k] - g.lower[k]) / (g.upper[k] - g.lower[k]) * float(g.dims[k] - 1);
        t = std::isfinite(t) ? std::min(std::max(t, 0.0f), float(g.dims[k] - 1)) : 0.0f;
        c[k] = std::min(int(t), int(g.dims[k]) - 2);
        f[k] = t - float(c[k]);
    }
}

// The 8 probes around p and their trilinear weights (corner bit 0: +x, bit 1: +y, bit 2: +z).
void corners(const ShProbeGrid& g, const glm::vec3& p, size_t index[8], float weight[8]) {
    int c[3];
    float f[3];
    locate(g, p, c, f);
    for (int corner = 0; corner < 8; ++corner) {
        int dx = corner & 1, dy = (corner >> 1) & 1, dz = corner >> 2;
        weight[corner] = (dx ? f[0] : 1 - f[0]) * (dy ? f[1] : 1 - f[1]) * (dz ? f[2] : 1 - f[2]);
        index[corner] = (size_t(c[2] + dz) * g.dims[1] + size_t(c[1] + dy)) * g.dims[0] + size_t(c[0] + dx);
    }
}

// Inverts a symmetric positive definite 9 x 9 matrix (Cholesky); false if it is not numerically so.
bool invertSpd9(const double m[9][9], double* inverse) {
    double l[9][9] = {};
    for (int i = 0; i < 9; ++i)
        for (int k = 0; k <= i; ++k) {
            double s = m[i][k];
            for (int j = 0; j < k; ++j) s -= l[i][j] * l[k][j];
            if (i == k) {
                if (!(s > 0.0)) return false;
                l[i][i] = std::sqrt(s);
            } else {
                l[i][k] = s / l[k][k];
            }
        }
    for (int col = 0; col < 9; ++col) {  // solve L L^T x = e_col
        double t[9];
        for (int i = 0; i < 9; ++i) {
            double s = i == col ? 1.0 : 0.0;
            for (int j = 0; j < i; ++j) s -= l[i][j] * t[j];
            t[i] = s / l[i][i];
        }
        for (int i = 8; i >= 0; --i) {
            double s = t[i];
            for (int j = i + 1; j < 9; ++j) s -= l[j][i] * t[j];
            t[i] = s / l[i][i];
        }
        for (int i = 0; i < 9; ++i) inverse[i * 9 + col] = t[i];
    }
    return std::isfinite(inverse[0]);
}

}  // namespace

void shBasis(const glm::vec3& d, float y[9]) {
    y[0] = 0.282094792f;
    y[1] = 0.488602512f * d.y;
    y[2] = 0.488602512f * d.z;
    y[3] = 0.488602512f * d.x;
    y[4] = 1.092548431f * d.x * d.y;
    y[5] = 1.092548431f * d.y * d.z;
    y[6] = 0.315391565f * (3.0f * d.z * d.z - 1.0f);
    y[7] = 1.092548431f * d.x * d.z;
    y[8] = 0.546274215f * (d.x * d.x - d.y * d.y);
}

glm::vec3 ShProbeGrid::evaluate(const glm::vec3& p, const glm::vec3& wo) const {
    size_t index[8];
    float weight[8], y[9];
    corners(*this, p, index, weight);
    shBasis(wo, y);
    glm::vec3 L(0.0f);
    for (int corner = 0; corner < 8; ++corner) {
        const float* c = &coeffs[index[corner] * 27];
        for (int ch = 0; ch < 3; ++ch) {
            float s = 0.0f;
            for (int i = 0; i < 9; ++i) s += c[ch * 9 + i] * y[i];
            L[ch] += weight[corner] * s;
        }
    }
    return glm::max(L, glm::vec3(0.0f));
}

glm::uvec3 probeDimsForBudget(const glm::vec3& lower, const glm::vec3& upper, size_t byteBudget) {
    const size_t perProbe = 27 * 2;
    glm::vec3 extent = glm::max(upper - lower, glm::vec3(1e-6f));
    glm::uvec3 dims(2);
    // Grow the axis with the widest spacing while the budget allows.
    for (;;) {
        int axis = 0;
        float widest = -1.0f;
        for (int k = 0; k < 3; ++k) {
            float spacing = extent[k] / float(dims[k] - 1);
            if (spacing > widest) widest = spacing, axis = k;
        }
        glm::uvec3 next = dims;
        ++next[axis];
        if (size_t(next.x) * next.y * next.z * perProbe > byteBudget) break;
        dims = next;
    }
    return dims;
}

namespace {

// The fit, compiled for the baseline ISA and, on x86-64, for AVX2 and for AVX-512F (-ffp-contract=off for this
// file: no fused multiply-adds, and the compilers reorder no sum, so each gives the same bits); the widest the
// CPU has runs. The functions a target region defines take its ISA (lambdas too); std's templates keep the
// baseline's, so no out-of-line copy of theirs needs more than the CPU has.
namespace sh_fit_plain {
#include "baker/validate/sh_fit_impl.h"
}  // namespace sh_fit_plain
#if defined(__x86_64__) && defined(__GNUC__) && !defined(__clang__)  // (GCC's target pragmas; elsewhere the plain fit)
#define NRAD_SH_FIT_X86 1
#pragma GCC push_options
#pragma GCC target("avx2")
namespace sh_fit_avx2 {
#include "baker/validate/sh_fit_impl.h"
}  // namespace sh_fit_avx2
#pragma GCC pop_options
#pragma GCC push_options
#pragma GCC target("avx512f,avx2")
namespace sh_fit_avx512 {
#include "baker/validate/sh_fit_impl.h"
}  // namespace sh_fit_avx512
#pragma GCC pop_options
#endif

using SolveProbes = std::vector<double> (*)(const ShProbeGrid&, const std::vector<TrainingSample>&, double,
                                            const std::function<void(double)>&, ShFitStats&);

struct ShFitKernel {
    const char* name;
    SolveProbes solve;
};

std::vector<ShFitKernel> fitKernels() {
    std::vector<ShFitKernel> out;
#ifdef NRAD_SH_FIT_X86
    __builtin_cpu_init();
    if (__builtin_cpu_supports("avx512f")) out.push_back({"avx512", sh_fit_avx512::solveProbes});
    if (__builtin_cpu_supports("avx2")) out.push_back({"avx2", sh_fit_avx2::solveProbes});
#endif
    out.push_back({"plain", sh_fit_plain::solveProbes});
    return out;
}

// The solution rounded to fp16 (clamped to its range; non-finite values 0), channel-major per probe as the
// grid stores it.
void storeCoefficients(ShProbeGrid& g, const std::vector<double>& x) {
    const size_t probes = g.probeCount();
    g.coeffs.assign(probes * 27, 0.0f);
    for (size_t probe = 0; probe < probes; ++probe)
        for (int i = 0; i < 9; ++i)
            for (int ch = 0; ch < 3; ++ch) {
                const double v = x[(probe * 9 + size_t(i)) * 3 + size_t(ch)];
                const float h = std::isfinite(v) ? float(std::clamp(v, -65504.0, 65504.0)) : 0.0f;
                g.coeffs[probe * 27 + size_t(ch) * 9 + size_t(i)] = format::halfToFloat(format::floatToHalf(h));
            }
}

// The fitted (fp16) grid's relMSE on the samples, in fixed blocks of samples.
double trainRelMse(const ShProbeGrid& g, const std::vector<TrainingSample>& samples) {
    const size_t n = samples.size();
    const double rel = sh_fit_plain::sumInBlocks<1>(n, 4096, [&](size_t s, double* sums) {
        const TrainingSample& t = samples[s];
        const glm::vec3 L = g.evaluate(t.position, t.wo);
        for (int ch = 0; ch < 3; ++ch) sums[0] += relMseTerm(double(L[ch]), double(t.radiance[ch]));
    })[0];
    return n > 0 ? rel / double(3 * n) : 0.0;
}

}  // namespace

std::vector<std::string> shFitKernels() {
    std::vector<std::string> names;
    for (const ShFitKernel& k : fitKernels()) names.emplace_back(k.name);
    return names;
}

ShProbeGrid fitShProbeGrid(const std::vector<TrainingSample>& samples, const glm::vec3& lower, const glm::vec3& upper,
                           const glm::uvec3& dims, ShFitStats* stats, double ridge, const std::function<void(double)>& progress,
                           const std::string& kernel) {
    ShProbeGrid g;
    g.dims = glm::max(dims, glm::uvec3(2));
    g.lower = lower;
    g.upper = upper;
    const std::vector<ShFitKernel> kernels = fitKernels();
    SolveProbes solve = kernels.front().solve;
    for (const ShFitKernel& k : kernels)
        if (kernel == k.name) solve = k.solve;
    if (!kernel.empty() && std::none_of(kernels.begin(), kernels.end(), [&](const ShFitKernel& k) { return kernel == k.name; }))
        throw std::invalid_argument("fitShProbeGrid: no fit kernel '" + kernel + "' on this CPU");
    ShFitStats st;
    double reported = 0.0;
    std::function<void(double)> report;
    if (progress) report = [&](double fraction) { progress(reported = fraction); };
    storeCoefficients(g, solve(g, samples, ridge, report, st));
    st.trainRelMse = trainRelMse(g, samples);
    if (progress && reported < 1.0) progress(1.0);
    if (stats) *stats = st;
    return g;
}

}  // namespace nrad
