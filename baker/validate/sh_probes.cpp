// L2 SH probe grid: basis, trilinear weights, least-squares fit by conjugate gradients (in parallel, with
// every sum in a fixed order: the same coefficients whatever the number of threads).
#include "baker/validate/sh_probes.h"

#include <algorithm>
#include <array>
#include <cmath>

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

// Sums body(i, sums) over i in [0, count), in fixed blocks of `block` (in parallel), each block's N sums
// added in block order: the same whatever the number of threads.
template <size_t N, class Body>
std::array<double, N> sumInBlocks(size_t count, size_t block, Body body) {
    const size_t blocks = (count + block - 1) / block;
    std::vector<std::array<double, N>> part(blocks);
    tbb::parallel_for(size_t(0), blocks, [&](size_t b) {
        part[b].fill(0.0);
        for (size_t i = b * block; i < std::min(count, (b + 1) * block); ++i) body(i, part[b].data());
    });
    std::array<double, N> sum{};
    for (const std::array<double, N>& p : part)
        for (size_t k = 0; k < N; ++k) sum[k] += p[k];
    return sum;
}

// The least-squares system over the probe lattice: the samples grouped by lattice cell, and the passes over
// cells and probes the fit is made of. Unknowns: 9 coefficients x 3 channels per probe,
// x[(probe * 9 + i) * 3 + channel]; the three channels share the matrix A (one row per sample: trilinear
// weight x basis value), so they are solved together.
class ProbeSystem {
public:
    ProbeSystem(const ShProbeGrid& grid, const std::vector<TrainingSample>& samples)
        : g(grid), cd(grid.dims - glm::uvec3(1)), cells(size_t(cd.x) * cd.y * cd.z), probes(grid.probeCount()), n(samples.size()),
          strideY(size_t(grid.dims.x)), strideZ(size_t(grid.dims.x) * grid.dims.y), contrib(cells * 8 * slot) {
        groupByCell(samples);
    }

    const ShProbeGrid& g;
    const glm::uvec3 cd;  // lattice cells per axis
    const size_t cells, probes, n, strideY, strideZ;
    // Cell c's samples are [cellStart[c], cellStart[c + 1]), each as its three cell fractions (its trilinear
    // weights) f, nine basis values y and target b.
    std::vector<size_t> cellStart;
    std::vector<float> f, y, b;

    // contrib[(cell * 8 + corner) * slot + j]: what a cell's samples add to its corner probes' 27 unknowns
    // (slot 27), or to the 45 entries of their blocks of A^T A (slot 45, once).
    static constexpr size_t kSlot = 45;
    void useSlot(size_t width) {
        slot = width;
        contrib.resize(cells * 8 * slot);
        contrib.shrink_to_fit();
    }

    // One pass over the cells (in parallel; each cell's samples in order). perSample(j, w, xc, acc): sample
    // j with corner weights w, the corners' current unknowns xc (when x is given) adds to acc.
    template <class PerSample>
    void cellPass(const double* x, PerSample perSample) {
        tbb::parallel_for(tbb::blocked_range<size_t>(0, cells, 16), [&](const tbb::blocked_range<size_t>& range) {
            double xc[8][27];
            for (size_t cell = range.begin(); cell != range.end(); ++cell) {
                double* acc = &contrib[cell * 8 * slot];
                std::fill(acc, acc + 8 * slot, 0.0);
                if (cellStart[cell] == cellStart[cell + 1]) continue;
                if (x) {
                    size_t probe[8];
                    cornerProbes(cell, probe);
                    for (int c = 0; c < 8; ++c) std::copy(x + probe[c] * 27, x + probe[c] * 27 + 27, xc[c]);
                }
                for (size_t j = cellStart[cell]; j != cellStart[cell + 1]; ++j) {
                    const double fx = f[j * 3], fy = f[j * 3 + 1], fz = f[j * 3 + 2];
                    double w[8];
                    for (int c = 0; c < 8; ++c)
                        w[c] = ((c & 1) ? fx : 1.0 - fx) * ((c & 2) ? fy : 1.0 - fy) * ((c & 4) ? fz : 1.0 - fz);
                    perSample(j, w, xc, acc);
                }
            }
        });
    }

    // Per probe, in fixed blocks of probes: body(probe, sums); the sums added in order.
    template <class Body>
    std::array<double, 6> perProbe(Body body) const {
        return sumInBlocks<6>(probes, 256, body);
    }

    // Gathers every probe's `width` values from the (up to 8) cells around it, in a fixed order, then
    // finish(probe, values, sums) uses them and may add to its block's 6 sums. Returns the sums (perProbe's).
    template <class Finish>
    std::array<double, 6> gather(size_t width, Finish finish) const {
        return perProbe([&](size_t probe, double* sums) {
            const size_t px = probe % g.dims.x, py = probe / strideY % g.dims.y, pz = probe / strideZ;
            double v[kSlot] = {};
            for (int c = 0; c < 8; ++c) {  // the cell of which this probe is corner c
                const size_t dx = (c & 1) ? 1 : 0, dy = (c & 2) ? 1 : 0, dz = (c & 4) ? 1 : 0;
                if (px < dx || py < dy || pz < dz || px - dx >= cd.x || py - dy >= cd.y || pz - dz >= cd.z) continue;
                const size_t cell = ((pz - dz) * cd.y + (py - dy)) * cd.x + (px - dx);
                const double* a = &contrib[(cell * 8 + size_t(c)) * slot];
                for (size_t j = 0; j < width; ++j) v[j] += a[j];
            }
            finish(probe, v, sums);
        });
    }

private:
    size_t slot = kSlot;
    std::vector<double> contrib;

    void cornerProbes(size_t cell, size_t probe[8]) const {
        const size_t cx = cell % cd.x, cy = cell / cd.x % cd.y, cz = cell / (size_t(cd.x) * cd.y);
        const size_t base = cz * strideZ + cy * strideY + cx;
        for (int c = 0; c < 8; ++c) probe[c] = base + ((c & 1) ? 1 : 0) + ((c & 2) ? strideY : 0) + ((c & 4) ? strideZ : 0);
    }

    // The samples grouped by the lattice cell they lie in (counting sort, stable: within a cell in sample
    // order), each as its three cell fractions, nine basis values and target.
    void groupByCell(const std::vector<TrainingSample>& samples) {
        std::vector<uint32_t> cellOfSample(n);
        std::vector<float> frac(n * 3);
        tbb::parallel_for(tbb::blocked_range<size_t>(0, n, 4096), [&](const tbb::blocked_range<size_t>& range) {
            for (size_t s = range.begin(); s != range.end(); ++s) {
                int c[3];
                locate(g, samples[s].position, c, &frac[s * 3]);
                cellOfSample[s] = uint32_t((size_t(c[2]) * cd.y + size_t(c[1])) * cd.x + size_t(c[0]));
            }
        });
        cellStart.assign(cells + 1, 0);
        for (uint32_t c : cellOfSample) ++cellStart[size_t(c) + 1];
        for (size_t c = 0; c < cells; ++c) cellStart[c + 1] += cellStart[c];
        std::vector<size_t> order(n);
        {
            std::vector<size_t> next(cellStart.begin(), cellStart.end() - 1);
            for (size_t s = 0; s < n; ++s) order[next[cellOfSample[s]]++] = s;
        }
        f.resize(n * 3);
        y.resize(n * 9);
        b.resize(n * 3);
        tbb::parallel_for(tbb::blocked_range<size_t>(0, n, 4096), [&](const tbb::blocked_range<size_t>& range) {
            for (size_t j = range.begin(); j != range.end(); ++j) {
                const TrainingSample& t = samples[order[j]];
                for (int k = 0; k < 3; ++k) {
                    f[j * 3 + size_t(k)] = frac[order[j] * 3 + size_t(k)];
                    b[j * 3 + size_t(k)] = t.radiance[k];
                }
                shBasis(t.wo, &y[j * 9]);
            }
        });
    }
};

// The preconditioner: per probe, (block + lambda)^-1 (row-major), with lambda the ridge.
struct Preconditioner {
    double lambda = 0.0;
    std::vector<double> inverse;
    void apply(size_t probe, const double* r, double* z) const {  // z = M^-1 r for the probe's 27
        const double* inv = &inverse[probe * 81];
        for (int i = 0; i < 9; ++i) {
            double t[3] = {0.0, 0.0, 0.0};
            for (int k = 0; k < 9; ++k)
                for (int ch = 0; ch < 3; ++ch) t[ch] += inv[i * 9 + k] * r[k * 3 + ch];
            for (int ch = 0; ch < 3; ++ch) z[i * 3 + ch] = t[ch];
        }
    }
};

// Each probe's 9 x 9 block of A^T A (upper triangle, the same for the three channels): its inverse, with
// the ridge, is the preconditioner (block Jacobi: a probe's nine basis functions are far from orthogonal
// over the half-sphere of directions a wall's samples leave by, which plain Jacobi leaves to the
// iterations). The ridge is relative to the mean of A^T A's diagonal.
Preconditioner blockJacobi(ProbeSystem& sys, double ridge) {
    constexpr size_t kSlot = ProbeSystem::kSlot;
    sys.cellPass(nullptr, [&](size_t j, const double w[8], const double(*)[27], double* acc) {
        double yy[kSlot];
        for (int i = 0, e = 0; i < 9; ++i)
            for (int k = i; k < 9; ++k, ++e) yy[e] = double(sys.y[j * 9 + size_t(i)]) * double(sys.y[j * 9 + size_t(k)]);
        for (int c = 0; c < 8; ++c) {
            const double ww = w[c] * w[c];
            for (size_t e = 0; e < kSlot; ++e) acc[size_t(c) * kSlot + e] += ww * yy[e];
        }
    });
    const size_t probes = sys.probes;
    std::vector<double> diagonalBlocks(probes * kSlot);
    const double trace = sys.gather(kSlot, [&](size_t probe, const double* v, double* sums) {
        std::copy(v, v + kSlot, &diagonalBlocks[probe * kSlot]);
        for (int i = 0, e = 0; i < 9; ++i)
            for (int k = i; k < 9; ++k, ++e)
                if (k == i) sums[0] += v[e];
    })[0];
    const double meanDiag = probes > 0 ? trace / double(probes * 9) : 0.0;
    Preconditioner M;
    const double lambda = M.lambda = std::max(ridge * meanDiag, 1e-12);
    M.inverse.resize(probes * 81);
    sys.perProbe([&](size_t probe, double*) {
        double m[9][9];
        for (int i = 0, e = 0; i < 9; ++i)
            for (int k = i; k < 9; ++k, ++e) m[i][k] = m[k][i] = diagonalBlocks[probe * kSlot + size_t(e)] + (k == i ? lambda : 0.0);
        double* inv = &M.inverse[probe * 81];
        if (!invertSpd9(m, inv)) {  // (not expected: the block is positive semi-definite, the ridge positive)
            std::fill(inv, inv + 81, 0.0);
            for (int i = 0; i < 9; ++i) inv[i * 9 + i] = m[i][i] > 0.0 ? 1.0 / m[i][i] : 1.0 / lambda;
        }
    });
    std::vector<double>().swap(diagonalBlocks);
    sys.useSlot(27);
    return M;
}

// rhs = A^T b; `norm` receives its norm per channel.
std::vector<double> normalRhs(ProbeSystem& sys, std::array<double, 6>& norm) {
    std::vector<double> rhs(sys.probes * 27);
    sys.cellPass(nullptr, [&](size_t j, const double w[8], const double(*)[27], double* acc) {
        double u[27];
        for (int i = 0; i < 9; ++i)
            for (int ch = 0; ch < 3; ++ch) u[i * 3 + ch] = double(sys.y[j * 9 + size_t(i)]) * double(sys.b[j * 3 + size_t(ch)]);
        for (int c = 0; c < 8; ++c)
            for (int k = 0; k < 27; ++k) acc[size_t(c) * 27 + size_t(k)] += w[c] * u[k];
    });
    norm = sys.gather(27, [&](size_t probe, const double* v, double* sums) {
        for (int k = 0; k < 27; ++k) {
            rhs[probe * 27 + size_t(k)] = v[k];
            sums[k % 3] += v[k] * v[k];
        }
    });
    for (double& v : norm) v = std::sqrt(v);
    return rhs;
}

// Stopping, per channel: the relative residual below 1e-7, or the objective falling by less than kStall of
// itself over the last kWindow iterations (each step lowers J by exactly alpha r.z). The directions still
// moving then are those no sample, and so no pixel, sees; docs/usage.md ("Baseline") has the sweep that
// chose 1e-2.
constexpr double kStall = 1e-2;
constexpr size_t kWindow = 10;

// Preconditioned conjugate gradients on (A^T A + lambda) x = A^T b, the three channels side by side, each
// with its own step sizes and stopping when its relative residual is below 1e-7 or its objective stalls.
struct ConjugateGradients {
    ProbeSystem& sys;
    const Preconditioner& M;
    std::vector<double> x, r, z, p, Ap;
    std::array<double, 6> rhsNorm{};
    std::array<double, 3> objective{}, rz{}, residual{};
    std::array<int, 3> iterations{};
    std::array<bool, 3> active{};
    std::array<std::vector<double>, 3> history;

    ConjugateGradients(ProbeSystem& equations, const Preconditioner& preconditioner)
        : sys(equations), M(preconditioner), x(equations.probes * 27, 0.0), z(x.size()), p(x.size()), Ap(x.size()) {
        r = normalRhs(sys, rhsNorm);
        startObjective();
        start();
    }

    bool running() const { return active[0] || active[1] || active[2]; }

    // The objective per channel, J(x) = |A x - b|^2 + lambda |x|^2: J(0) = |b|^2 (fixed blocks of samples).
    void startObjective() {
        objective = sumInBlocks<3>(sys.n, 4096, [&](size_t j, double* sums) {
            for (size_t ch = 0; ch < 3; ++ch) sums[ch] += double(sys.b[j * 3 + ch]) * double(sys.b[j * 3 + ch]);
        });
        for (size_t ch = 0; ch < 3; ++ch) history[ch].push_back(objective[ch]);
    }

    // z = M^-1 r, p = z, from x = 0.
    void start() {
        const std::array<double, 6> s = sys.perProbe([&](size_t probe, double* sums) {
            M.apply(probe, &r[probe * 27], &z[probe * 27]);
            for (size_t k = probe * 27; k < probe * 27 + 27; ++k) {
                p[k] = z[k];
                sums[k % 3] += r[k] * z[k];
            }
        });
        for (size_t ch = 0; ch < 3; ++ch) {
            rz[ch] = s[ch];
            residual[ch] = rhsNorm[ch] > 0.0 ? 1.0 : 0.0;
            active[ch] = residual[ch] > 1e-7;
        }
    }

    // Ap = (A^T A + lambda) p; returns p.Ap per channel.
    std::array<double, 6> applyNormal() {
        sys.cellPass(p.data(), [&](size_t j, const double w[8], const double(*xc)[27], double* acc) {
            double v[27] = {};
            for (int c = 0; c < 8; ++c)
                for (int k = 0; k < 27; ++k) v[k] += w[c] * xc[c][k];
            double t[3] = {0.0, 0.0, 0.0};  // (A p) at this sample, per channel
            for (int i = 0; i < 9; ++i)
                for (int ch = 0; ch < 3; ++ch) t[ch] += v[i * 3 + ch] * double(sys.y[j * 9 + size_t(i)]);
            double u[27];
            for (int i = 0; i < 9; ++i)
                for (int ch = 0; ch < 3; ++ch) u[i * 3 + ch] = double(sys.y[j * 9 + size_t(i)]) * t[ch];
            for (int c = 0; c < 8; ++c)
                for (int k = 0; k < 27; ++k) acc[size_t(c) * 27 + size_t(k)] += w[c] * u[k];
        });
        return sys.gather(27, [&](size_t probe, const double* v, double* sums) {
            for (int k = 0; k < 27; ++k) {
                const size_t e = probe * 27 + size_t(k);
                Ap[e] = v[k] + M.lambda * p[e];
                sums[k % 3] += p[e] * Ap[e];
            }
        });
    }

    // x += alpha p, r -= alpha Ap, z = M^-1 r; returns r.r (0..2) and r.z (3..5) per channel.
    std::array<double, 6> step(const double alpha[3]) {
        return sys.perProbe([&](size_t probe, double* sums) {
            const size_t k0 = probe * 27;
            for (size_t k = k0; k < k0 + 27; ++k) {
                const size_t ch = k % 3;
                if (!active[ch]) continue;
                x[k] += alpha[ch] * p[k];
                r[k] -= alpha[ch] * Ap[k];
            }
            M.apply(probe, &r[k0], &z[k0]);
            for (size_t k = k0; k < k0 + 27; ++k) {
                const size_t ch = k % 3;
                if (!active[ch]) continue;
                sums[ch] += r[k] * r[k];
                sums[3 + ch] += r[k] * z[k];
            }
        });
    }

    void iterate() {
        const std::array<double, 6> pAp = applyNormal();
        double alpha[3] = {0.0, 0.0, 0.0};
        for (size_t ch = 0; ch < 3; ++ch) {
            if (!active[ch]) continue;
            if (!(pAp[ch] > 0.0)) {
                active[ch] = false;
                continue;
            }
            alpha[ch] = rz[ch] / pAp[ch];
        }
        const std::array<double, 6> s = step(alpha);
        double beta[3] = {0.0, 0.0, 0.0};
        bool stalled[3] = {false, false, false};
        for (size_t ch = 0; ch < 3; ++ch) {
            if (!active[ch]) continue;
            ++iterations[ch];
            objective[ch] -= alpha[ch] * rz[ch];
            history[ch].push_back(objective[ch]);
            const size_t h = history[ch].size();
            stalled[ch] = h > kWindow && history[ch][h - 1 - kWindow] - objective[ch] <= kStall * objective[ch];
            residual[ch] = std::sqrt(s[ch]) / rhsNorm[ch];
            beta[ch] = s[3 + ch] / rz[ch];
            rz[ch] = s[3 + ch];
        }
        sys.perProbe([&](size_t probe, double*) {
            for (size_t k = probe * 27; k < probe * 27 + 27; ++k)
                if (active[k % 3]) p[k] = z[k] + beta[k % 3] * p[k];
        });
        for (size_t ch = 0; ch < 3; ++ch) active[ch] = active[ch] && residual[ch] > 1e-7 && !stalled[ch];
    }

    // The slowest channel's way to either criterion, on log scales.
    double fractionDone() const {
        const double logTarget = std::log(1e-7), logStall = std::log(kStall);
        double fraction = 1.0;
        for (size_t ch = 0; ch < 3; ++ch) {
            if (!active[ch]) continue;
            const std::vector<double>& h = history[ch];
            const double fall = (h[h.size() > kWindow ? h.size() - 1 - kWindow : 0] - h.back()) / h.back();
            const double stall = fall > 0.0 ? std::clamp(std::log(fall) / logStall, 0.0, 1.0) : 1.0;
            fraction = std::min(fraction, std::max(stall, std::clamp(std::log(residual[ch]) / logTarget, 0.0, 1.0)));
        }
        return fraction;
    }
};

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
    const double rel = sumInBlocks<1>(n, 4096, [&](size_t s, double* sums) {
        const TrainingSample& t = samples[s];
        const glm::vec3 L = g.evaluate(t.position, t.wo);
        for (int ch = 0; ch < 3; ++ch) sums[0] += relMseTerm(double(L[ch]), double(t.radiance[ch]));
    })[0];
    return n > 0 ? rel / double(3 * n) : 0.0;
}

}  // namespace

ShProbeGrid fitShProbeGrid(const std::vector<TrainingSample>& samples, const glm::vec3& lower, const glm::vec3& upper,
                           const glm::uvec3& dims, ShFitStats* stats, double ridge, const std::function<void(double)>& progress) {
    ShProbeGrid g;
    g.dims = glm::max(dims, glm::uvec3(2));
    g.lower = lower;
    g.upper = upper;
    ProbeSystem sys(g, samples);
    const Preconditioner M = blockJacobi(sys, ridge);
    ConjugateGradients cg(sys, M);
    double reported = 0.0;
    for (int it = 0; it < 2000 && cg.running(); ++it) {
        cg.iterate();
        if (!progress) continue;
        const double fraction = cg.fractionDone();
        if (fraction > reported) progress(reported = fraction);
    }

    ShFitStats st;
    for (size_t ch = 0; ch < 3; ++ch) {
        st.iterations = std::max(st.iterations, cg.iterations[ch]);
        st.relativeResidual = std::max(st.relativeResidual, cg.residual[ch]);
    }
    storeCoefficients(g, cg.x);
    st.trainRelMse = trainRelMse(g, samples);
    if (progress && reported < 1.0) progress(1.0);
    if (stats) *stats = st;
    return g;
}

}  // namespace nrad
