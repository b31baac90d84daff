// sh_probes.cpp's fit, the part compiled once per ISA: the least-squares system over the probe lattice and
// its preconditioned conjugate gradients, as solveProbes(). Only sh_probes.cpp includes it, inside a namespace
// per ISA, after its own includes and its functions locate() and invertSpd9(): no guard, no includes of its own.

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
          strideY(size_t(grid.dims.x)), strideZ(size_t(grid.dims.x) * grid.dims.y) {
        groupByCell(samples);
    }

    const ShProbeGrid& g;
    const glm::uvec3 cd;  // lattice cells per axis
    const size_t cells, probes, n, strideY, strideZ;
    // Cell c's samples are [cellStart[c], cellStart[c + 1]), each as its three cell fractions (its trilinear
    // weights) f, nine basis values y and target b.
    std::vector<size_t> cellStart;
    std::vector<float> f, y, b;

    // One pass over the cells: a cell's samples, in order, add to the cell's own 8 x Width sums
    // (perSample(j, w, xc, acc): sample j with corner weights w, the corners' current unknowns xc when x is
    // given), which then add to its 8 corner probes' Width values in out (probes x Width, zeroed first). The
    // cells go in 8 classes by the parity of their coordinates, one class after another: no two cells of a
    // class share a probe, so a class runs in parallel with no per-cell buffer, and every probe receives its
    // cells in class order, whatever the number of threads.
    template <size_t Width, class PerSample>
    void cellPass(const double* x, double* out, PerSample perSample) const {
        tbb::parallel_for(tbb::blocked_range<size_t>(0, probes, 1024), [&](const tbb::blocked_range<size_t>& range) {
            std::fill(out + range.begin() * Width, out + range.end() * Width, 0.0);
        });
        for (size_t cls = 0; cls < 8; ++cls) {
            const size_t ox = cls & 1, oy = (cls >> 1) & 1, oz = cls >> 2;
            const size_t nx = (cd.x - ox + 1) / 2, ny = (cd.y - oy + 1) / 2, nz = (cd.z - oz + 1) / 2;
            tbb::parallel_for(tbb::blocked_range<size_t>(0, nx * ny * nz, 16), [&](const tbb::blocked_range<size_t>& range) {
                double xc[8][27], acc[8 * Width];
                for (size_t i = range.begin(); i != range.end(); ++i) {
                    const size_t cell = ((oz + 2 * (i / (nx * ny))) * cd.y + oy + 2 * (i / nx % ny)) * cd.x + ox + 2 * (i % nx);
                    if (cellStart[cell] == cellStart[cell + 1]) continue;
                    size_t probe[8];
                    cornerProbes(cell, probe);
                    if (x)
                        for (int c = 0; c < 8; ++c) std::copy(x + probe[c] * 27, x + probe[c] * 27 + 27, xc[c]);
                    std::fill(acc, acc + 8 * Width, 0.0);
                    for (size_t j = cellStart[cell]; j != cellStart[cell + 1]; ++j) {
                        const double fx = f[j * 3], fy = f[j * 3 + 1], fz = f[j * 3 + 2];
                        double w[8];
                        for (int c = 0; c < 8; ++c)
                            w[c] = ((c & 1) ? fx : 1.0 - fx) * ((c & 2) ? fy : 1.0 - fy) * ((c & 4) ? fz : 1.0 - fz);
                        perSample(j, w, xc, acc);
                    }
                    for (int c = 0; c < 8; ++c) {
                        double* o = out + probe[c] * Width;
                        for (size_t k = 0; k < Width; ++k) o[k] += acc[size_t(c) * Width + k];
                    }
                }
            });
        }
    }

    // Per probe, in fixed blocks of probes: body(probe, sums); the sums added in order.
    template <class Body>
    std::array<double, 6> perProbe(Body body) const {
        return sumInBlocks<6>(probes, 256, body);
    }

private:
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
Preconditioner blockJacobi(const ProbeSystem& sys, double ridge) {
    constexpr size_t kBlock = 45;  // the upper triangle of a 9 x 9 block
    const size_t probes = sys.probes;
    std::vector<double> diagonalBlocks(probes * kBlock);
    sys.cellPass<kBlock>(nullptr, diagonalBlocks.data(), [&](size_t j, const double w[8], const double(*)[27], double* acc) {
        double yy[kBlock];
        for (int i = 0, e = 0; i < 9; ++i)
            for (int k = i; k < 9; ++k, ++e) yy[e] = double(sys.y[j * 9 + size_t(i)]) * double(sys.y[j * 9 + size_t(k)]);
        for (int c = 0; c < 8; ++c) {
            const double ww = w[c] * w[c];
            for (size_t e = 0; e < kBlock; ++e) acc[size_t(c) * kBlock + e] += ww * yy[e];
        }
    });
    const double trace = sys.perProbe([&](size_t probe, double* sums) {
        for (int i = 0, e = 0; i < 9; ++i)
            for (int k = i; k < 9; ++k, ++e)
                if (k == i) sums[0] += diagonalBlocks[probe * kBlock + size_t(e)];
    })[0];
    const double meanDiag = probes > 0 ? trace / double(probes * 9) : 0.0;
    Preconditioner M;
    const double lambda = M.lambda = std::max(ridge * meanDiag, 1e-12);
    M.inverse.resize(probes * 81);
    sys.perProbe([&](size_t probe, double*) {
        double m[9][9];
        for (int i = 0, e = 0; i < 9; ++i)
            for (int k = i; k < 9; ++k, ++e) m[i][k] = m[k][i] = diagonalBlocks[probe * kBlock + size_t(e)] + (k == i ? lambda : 0.0);
        double* inv = &M.inverse[probe * 81];
        if (!invertSpd9(m, inv)) {  // (not expected: the block is positive semi-definite, the ridge positive)
            std::fill(inv, inv + 81, 0.0);
            for (int i = 0; i < 9; ++i) inv[i * 9 + i] = m[i][i] > 0.0 ? 1.0 / m[i][i] : 1.0 / lambda;
        }
    });
    return M;
}

// rhs = A^T b; `norm` receives its norm per channel.
std::vector<double> normalRhs(const ProbeSystem& sys, std::array<double, 6>& norm) {
    std::vector<double> rhs(sys.probes * 27);
    sys.cellPass<27>(nullptr, rhs.data(), [&](size_t j, const double w[8], const double(*)[27], double* acc) {
        double u[27];
        for (int i = 0; i < 9; ++i)
            for (int ch = 0; ch < 3; ++ch) u[i * 3 + ch] = double(sys.y[j * 9 + size_t(i)]) * double(sys.b[j * 3 + size_t(ch)]);
        for (int c = 0; c < 8; ++c)
            for (int k = 0; k < 27; ++k) acc[size_t(c) * 27 + size_t(k)] += w[c] * u[k];
    });
    norm = sys.perProbe([&](size_t probe, double* sums) {
        for (int k = 0; k < 27; ++k) sums[k % 3] += rhs[probe * 27 + size_t(k)] * rhs[probe * 27 + size_t(k)];
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
    const ProbeSystem& sys;
    const Preconditioner& M;
    std::vector<double> x, r, z, p, Ap;
    std::array<double, 6> rhsNorm{};
    std::array<double, 3> objective{}, rz{}, residual{};
    std::array<int, 3> iterations{};
    std::array<bool, 3> active{};
    std::array<std::vector<double>, 3> history;

    ConjugateGradients(const ProbeSystem& equations, const Preconditioner& preconditioner)
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
        sys.cellPass<27>(p.data(), Ap.data(), [&](size_t j, const double w[8], const double(*xc)[27], double* acc) {
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
        return sys.perProbe([&](size_t probe, double* sums) {
            for (int k = 0; k < 27; ++k) {
                const size_t e = probe * 27 + size_t(k);
                Ap[e] += M.lambda * p[e];
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

// The fit itself: x (probe * 27 + i * 3 + channel) and its statistics but trainRelMse.
std::vector<double> solveProbes(const ShProbeGrid& g, const std::vector<TrainingSample>& samples, double ridge,
                                const std::function<void(double)>& progress, ShFitStats& st) {
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
    for (size_t ch = 0; ch < 3; ++ch) {
        st.iterations = std::max(st.iterations, cg.iterations[ch]);
        st.relativeResidual = std::max(st.relativeResidual, cg.residual[ch]);
    }
    return std::move(cg.x);
}
