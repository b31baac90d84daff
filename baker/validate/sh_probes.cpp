// L2 SH probe grid: basis, trilinear weights, least-squares fit by conjugate gradients (in parallel, with
// every sum in a fixed order: the same coefficients whatever the number of threads).
#include "baker/validate/sh_probes.h"

#include <algorithm>
#include <array>
#include <cmath>

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <nrad/format.h>

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

ShProbeGrid fitShProbeGrid(const std::vector<TrainingSample>& samples, const glm::vec3& lower, const glm::vec3& upper,
                           const glm::uvec3& dims, ShFitStats* stats, double ridge, const std::function<void(double)>& progress) {
    ShProbeGrid g;
    g.dims = glm::max(dims, glm::uvec3(2));
    g.lower = lower;
    g.upper = upper;
    const size_t probes = g.probeCount(), n = samples.size();
    const glm::uvec3 cd = g.dims - glm::uvec3(1);  // lattice cells per axis
    const size_t cells = size_t(cd.x) * cd.y * cd.z;
    // The samples grouped by the lattice cell they lie in (counting sort, stable: within a cell in sample
    // order), each as its three cell fractions (its trilinear weights), nine basis values and target.
    std::vector<uint32_t> cellOfSample(n);
    std::vector<float> frac(n * 3);
    tbb::parallel_for(tbb::blocked_range<size_t>(0, n, 4096), [&](const tbb::blocked_range<size_t>& range) {
        for (size_t s = range.begin(); s != range.end(); ++s) {
            int c[3];
            locate(g, samples[s].position, c, &frac[s * 3]);
            cellOfSample[s] = uint32_t((size_t(c[2]) * cd.y + size_t(c[1])) * cd.x + size_t(c[0]));
        }
    });
    std::vector<size_t> cellStart(cells + 1, 0);
    for (uint32_t c : cellOfSample) ++cellStart[size_t(c) + 1];
    for (size_t c = 0; c < cells; ++c) cellStart[c + 1] += cellStart[c];
    std::vector<size_t> order(n);
    {
        std::vector<size_t> next(cellStart.begin(), cellStart.end() - 1);
        for (size_t s = 0; s < n; ++s) order[next[cellOfSample[s]]++] = s;
    }
    std::vector<float> f(n * 3), y(n * 9), b(n * 3);
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
    std::vector<uint32_t>().swap(cellOfSample);
    std::vector<float>().swap(frac);
    std::vector<size_t>().swap(order);

    // Unknowns: 9 coefficients x 3 channels per probe, x[(probe * 9 + i) * 3 + channel]; the three channels
    // share the matrix A (one row per sample: trilinear weight x basis value), so they are solved together.
    const size_t K = probes * 27;
    const size_t strideY = size_t(g.dims.x), strideZ = size_t(g.dims.x) * g.dims.y;
    auto cornerProbes = [&](size_t cell, size_t probe[8]) {
        const size_t cx = cell % cd.x, cy = cell / cd.x % cd.y, cz = cell / (size_t(cd.x) * cd.y);
        const size_t base = cz * strideZ + cy * strideY + cx;
        for (int c = 0; c < 8; ++c) probe[c] = base + ((c & 1) ? 1 : 0) + ((c & 2) ? strideY : 0) + ((c & 4) ? strideZ : 0);
    };
    // contrib[(cell * 8 + corner) * slot + j]: what a cell's samples add to its corner probes' 27 unknowns
    // (slot 27), or to the 45 entries of their blocks of A^T A (slot 45, once).
    constexpr size_t kSlot = 45;
    size_t slot = kSlot;
    std::vector<double> contrib(cells * 8 * slot);
    // One pass over the cells (in parallel; each cell's samples in order). perSample(j, w, xc, acc): sample
    // j with corner weights w, the corners' current unknowns xc (when x is given) adds to acc.
    auto cellPass = [&](const double* x, auto perSample) {
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
    };
    // Gathers every probe's `width` values from the (up to 8) cells around it, in a fixed order, then
    // finish(probe, values, sums) uses them and may add to its block's 6 sums. Returns the sums (over fixed
    // blocks of probes, added in order: the same whatever the threads).
    auto gather = [&](size_t width, auto finish) {
        constexpr size_t kBlock = 256;  // probes
        const size_t blocks = (probes + kBlock - 1) / kBlock;
        std::vector<std::array<double, 6>> part(blocks);
        tbb::parallel_for(size_t(0), blocks, [&](size_t block) {
            part[block].fill(0.0);
            for (size_t probe = block * kBlock; probe < std::min(probes, (block + 1) * kBlock); ++probe) {
                const size_t px = probe % g.dims.x, py = probe / strideY % g.dims.y, pz = probe / strideZ;
                double v[kSlot] = {};
                for (int c = 0; c < 8; ++c) {  // the cell of which this probe is corner c
                    const size_t dx = (c & 1) ? 1 : 0, dy = (c & 2) ? 1 : 0, dz = (c & 4) ? 1 : 0;
                    if (px < dx || py < dy || pz < dz || px - dx >= cd.x || py - dy >= cd.y || pz - dz >= cd.z) continue;
                    const size_t cell = ((pz - dz) * cd.y + (py - dy)) * cd.x + (px - dx);
                    const double* a = &contrib[(cell * 8 + size_t(c)) * slot];
                    for (size_t j = 0; j < width; ++j) v[j] += a[j];
                }
                finish(probe, v, part[block].data());
            }
        });
        std::array<double, 6> sum{};
        for (const std::array<double, 6>& p : part)
            for (size_t k = 0; k < 6; ++k) sum[k] += p[k];
        return sum;
    };
    // Per probe, in fixed blocks of probes: body(probe, sums); the sums added in order.
    auto perProbe = [&](auto body) {
        constexpr size_t kBlock = 256;
        const size_t blocks = (probes + kBlock - 1) / kBlock;
        std::vector<std::array<double, 6>> part(blocks);
        tbb::parallel_for(size_t(0), blocks, [&](size_t block) {
            part[block].fill(0.0);
            for (size_t probe = block * kBlock; probe < std::min(probes, (block + 1) * kBlock); ++probe) body(probe, part[block].data());
        });
        std::array<double, 6> sum{};
        for (const std::array<double, 6>& p : part)
            for (size_t k = 0; k < 6; ++k) sum[k] += p[k];
        return sum;
    };

    // Each probe's 9 x 9 block of A^T A (upper triangle, the same for the three channels): its inverse, with
    // the ridge, is the preconditioner (block Jacobi: a probe's nine basis functions are far from orthogonal
    // over the half-sphere of directions a wall's samples leave by, which plain Jacobi leaves to the
    // iterations). The ridge is relative to the mean of A^T A's diagonal.
    cellPass(nullptr, [&](size_t j, const double w[8], const double(*)[27], double* acc) {
        double yy[kSlot];
        for (int i = 0, e = 0; i < 9; ++i)
            for (int k = i; k < 9; ++k, ++e) yy[e] = double(y[j * 9 + size_t(i)]) * double(y[j * 9 + size_t(k)]);
        for (int c = 0; c < 8; ++c) {
            const double ww = w[c] * w[c];
            for (size_t e = 0; e < kSlot; ++e) acc[size_t(c) * slot + e] += ww * yy[e];
        }
    });
    std::vector<double> diagonalBlocks(probes * kSlot);
    const double trace = gather(kSlot, [&](size_t probe, const double* v, double* sums) {
        std::copy(v, v + kSlot, &diagonalBlocks[probe * kSlot]);
        for (int i = 0, e = 0; i < 9; ++i)
            for (int k = i; k < 9; ++k, ++e)
                if (k == i) sums[0] += v[e];
    })[0];
    const double meanDiag = probes > 0 ? trace / double(probes * 9) : 0.0;
    const double lambda = std::max(ridge * meanDiag, 1e-12);
    std::vector<double> precond(probes * 81);  // per probe, (block + lambda)^-1, row-major
    perProbe([&](size_t probe, double*) {
        double m[9][9];
        for (int i = 0, e = 0; i < 9; ++i)
            for (int k = i; k < 9; ++k, ++e) m[i][k] = m[k][i] = diagonalBlocks[probe * kSlot + size_t(e)] + (k == i ? lambda : 0.0);
        double* inv = &precond[probe * 81];
        if (!invertSpd9(m, inv)) {  // (not expected: the block is positive semi-definite, the ridge positive)
            std::fill(inv, inv + 81, 0.0);
            for (int i = 0; i < 9; ++i) inv[i * 9 + i] = m[i][i] > 0.0 ? 1.0 / m[i][i] : 1.0 / lambda;
        }
    });
    std::vector<double>().swap(diagonalBlocks);
    slot = 27;
    contrib.resize(cells * 8 * slot);
    contrib.shrink_to_fit();
    auto applyPrecond = [&](size_t probe, const double* r, double* z) {  // z = M^-1 r for the probe's 27
        const double* inv = &precond[probe * 81];
        for (int i = 0; i < 9; ++i) {
            double t[3] = {0.0, 0.0, 0.0};
            for (int k = 0; k < 9; ++k)
                for (int ch = 0; ch < 3; ++ch) t[ch] += inv[i * 9 + k] * r[k * 3 + ch];
            for (int ch = 0; ch < 3; ++ch) z[i * 3 + ch] = t[ch];
        }
    };

    // rhs = A^T b.
    std::vector<double> rhs(K);
    cellPass(nullptr, [&](size_t j, const double w[8], const double(*)[27], double* acc) {
        double u[27];
        for (int i = 0; i < 9; ++i)
            for (int ch = 0; ch < 3; ++ch) u[i * 3 + ch] = double(y[j * 9 + size_t(i)]) * double(b[j * 3 + size_t(ch)]);
        for (int c = 0; c < 8; ++c)
            for (int k = 0; k < 27; ++k) acc[size_t(c) * 27 + size_t(k)] += w[c] * u[k];
    });
    std::array<double, 6> rhsNorm = gather(27, [&](size_t probe, const double* v, double* sums) {
        for (int k = 0; k < 27; ++k) {
            rhs[probe * 27 + size_t(k)] = v[k];
            sums[k % 3] += v[k] * v[k];
        }
    });
    for (double& v : rhsNorm) v = std::sqrt(v);
    // The objective per channel, J(x) = |A x - b|^2 + lambda |x|^2: J(0) = |b|^2 (fixed blocks of samples).
    std::array<double, 3> objective{};
    {
        constexpr size_t kBlock = 4096;
        const size_t blocks = (n + kBlock - 1) / kBlock;
        std::vector<std::array<double, 3>> part(blocks);
        tbb::parallel_for(size_t(0), blocks, [&](size_t blk) {
            part[blk].fill(0.0);
            for (size_t j = blk * kBlock; j < std::min(n, (blk + 1) * kBlock); ++j)
                for (size_t ch = 0; ch < 3; ++ch) part[blk][ch] += double(b[j * 3 + ch]) * double(b[j * 3 + ch]);
        });
        for (const std::array<double, 3>& v : part)
            for (size_t ch = 0; ch < 3; ++ch) objective[ch] += v[ch];
    }

    // Preconditioned conjugate gradients on (A^T A + lambda) x = A^T b, the three channels side by side,
    // each with its own step sizes and stopping when its relative residual is below 1e-7.
    std::vector<double> x(K, 0.0), r = rhs, z(K), p(K), Ap(K);
    std::array<double, 3> rz{}, residual{};
    std::array<int, 3> iterations{};
    std::array<bool, 3> active{};
    {
        const std::array<double, 6> s = perProbe([&](size_t probe, double* sums) {
            applyPrecond(probe, &r[probe * 27], &z[probe * 27]);
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
    // Stopping, per channel: the relative residual below 1e-7, or the objective falling by less than kStall of
    // itself over the last kWindow iterations (each step lowers J by exactly alpha r.z). The directions still
    // moving then are those no sample, and so no pixel, sees; docs/usage.md ("Baseline") has the sweep that
    // chose 1e-2.
    constexpr double kStall = 1e-2;
    constexpr size_t kWindow = 10;
    std::array<std::vector<double>, 3> history;
    for (size_t ch = 0; ch < 3; ++ch) history[ch].push_back(objective[ch]);
    const double logTarget = std::log(1e-7), logStall = std::log(kStall);
    double reported = 0.0;
    auto report = [&]() {  // the slowest channel's way to either criterion, on log scales
        if (!progress) return;
        double fraction = 1.0;
        for (size_t ch = 0; ch < 3; ++ch) {
            if (!active[ch]) continue;
            const std::vector<double>& h = history[ch];
            const double fall = (h[h.size() > kWindow ? h.size() - 1 - kWindow : 0] - h.back()) / h.back();
            const double stall = fall > 0.0 ? std::clamp(std::log(fall) / logStall, 0.0, 1.0) : 1.0;
            fraction = std::min(fraction, std::max(stall, std::clamp(std::log(residual[ch]) / logTarget, 0.0, 1.0)));
        }
        if (fraction > reported) progress(reported = fraction);
    };
    for (int it = 0; it < 2000 && (active[0] || active[1] || active[2]); ++it) {
        cellPass(p.data(), [&](size_t j, const double w[8], const double(*xc)[27], double* acc) {
            double v[27] = {};
            for (int c = 0; c < 8; ++c)
                for (int k = 0; k < 27; ++k) v[k] += w[c] * xc[c][k];
            double t[3] = {0.0, 0.0, 0.0};  // (A p) at this sample, per channel
            for (int i = 0; i < 9; ++i)
                for (int ch = 0; ch < 3; ++ch) t[ch] += v[i * 3 + ch] * double(y[j * 9 + size_t(i)]);
            double u[27];
            for (int i = 0; i < 9; ++i)
                for (int ch = 0; ch < 3; ++ch) u[i * 3 + ch] = double(y[j * 9 + size_t(i)]) * t[ch];
            for (int c = 0; c < 8; ++c)
                for (int k = 0; k < 27; ++k) acc[size_t(c) * 27 + size_t(k)] += w[c] * u[k];
        });
        const std::array<double, 6> pAp = gather(27, [&](size_t probe, const double* v, double* sums) {
            for (int k = 0; k < 27; ++k) {
                const size_t e = probe * 27 + size_t(k);
                Ap[e] = v[k] + lambda * p[e];
                sums[k % 3] += p[e] * Ap[e];
            }
        });
        double alpha[3] = {0.0, 0.0, 0.0};
        for (size_t ch = 0; ch < 3; ++ch) {
            if (!active[ch]) continue;
            if (!(pAp[ch] > 0.0)) {
                active[ch] = false;
                continue;
            }
            alpha[ch] = rz[ch] / pAp[ch];
        }
        // x += alpha p, r -= alpha Ap, z = M^-1 r; sums: r.r and r.z per channel.
        const std::array<double, 6> s = perProbe([&](size_t probe, double* sums) {
            const size_t k0 = probe * 27;
            for (size_t k = k0; k < k0 + 27; ++k) {
                const size_t ch = k % 3;
                if (!active[ch]) continue;
                x[k] += alpha[ch] * p[k];
                r[k] -= alpha[ch] * Ap[k];
            }
            applyPrecond(probe, &r[k0], &z[k0]);
            for (size_t k = k0; k < k0 + 27; ++k) {
                const size_t ch = k % 3;
                if (!active[ch]) continue;
                sums[ch] += r[k] * r[k];
                sums[3 + ch] += r[k] * z[k];
            }
        });
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
        perProbe([&](size_t probe, double*) {
            for (size_t k = probe * 27; k < probe * 27 + 27; ++k)
                if (active[k % 3]) p[k] = z[k] + beta[k % 3] * p[k];
        });
        for (size_t ch = 0; ch < 3; ++ch) active[ch] = active[ch] && residual[ch] > 1e-7 && !stalled[ch];
        report();
    }

    ShFitStats st;
    g.coeffs.assign(probes * 27, 0.0f);
    for (size_t ch = 0; ch < 3; ++ch) {
        st.iterations = std::max(st.iterations, iterations[ch]);
        st.relativeResidual = std::max(st.relativeResidual, residual[ch]);
    }
    for (size_t probe = 0; probe < probes; ++probe)
        for (int i = 0; i < 9; ++i)
            for (int ch = 0; ch < 3; ++ch) {
                const double v = x[(probe * 9 + size_t(i)) * 3 + size_t(ch)];
                const float h = std::isfinite(v) ? float(std::clamp(v, -65504.0, 65504.0)) : 0.0f;
                g.coeffs[probe * 27 + size_t(ch) * 9 + size_t(i)] = format::halfToFloat(format::floatToHalf(h));
            }
    // The fitted (fp16) grid's relMSE on the samples, in fixed blocks of samples.
    {
        constexpr size_t kBlock = 4096;
        const size_t blocks = (n + kBlock - 1) / kBlock;
        std::vector<double> part(blocks, 0.0);
        tbb::parallel_for(size_t(0), blocks, [&](size_t block) {
            for (size_t s = block * kBlock; s < std::min(n, (block + 1) * kBlock); ++s) {
                const TrainingSample& t = samples[s];
                const glm::vec3 L = g.evaluate(t.position, t.wo);
                for (int ch = 0; ch < 3; ++ch) {
                    const double d = double(L[ch]) - double(t.radiance[ch]);
                    part[block] += d * d / (double(t.radiance[ch]) * double(t.radiance[ch]) + 0.01);
                }
            }
        });
        double rel = 0.0;
        for (double v : part) rel += v;
        st.trainRelMse = n > 0 ? rel / double(3 * n) : 0.0;
    }
    if (progress && reported < 1.0) progress(1.0);
    if (stats) *stats = st;
    return g;
}

}  // namespace nrad
