// L2 SH probe grid: basis, trilinear weights, least-squares fit by conjugate gradients.
#include "baker/validate/sh_probes.h"

#include <algorithm>
#include <cmath>

#include <nrad/format.h>

namespace nrad {

namespace {

// The 8 probes around p and their trilinear weights.
void corners(const ShProbeGrid& g, const glm::vec3& p, size_t index[8], float weight[8]) {
    int c[3];
    float f[3];
    for (int k = 0; k < 3; ++k) {
        float t = (p[k] - g.lower[k]) / (g.upper[k] - g.lower[k]) * float(g.dims[k] - 1);
        t = std::isfinite(t) ? std::min(std::max(t, 0.0f), float(g.dims[k] - 1)) : 0.0f;
        c[k] = std::min(int(t), int(g.dims[k]) - 2);
        f[k] = t - float(c[k]);
    }
    for (int corner = 0; corner < 8; ++corner) {
        int dx = corner & 1, dy = (corner >> 1) & 1, dz = corner >> 2;
        weight[corner] = (dx ? f[0] : 1 - f[0]) * (dy ? f[1] : 1 - f[1]) * (dz ? f[2] : 1 - f[2]);
        index[corner] = (size_t(c[2] + dz) * g.dims[1] + size_t(c[1] + dy)) * g.dims[0] + size_t(c[0] + dx);
    }
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
                           const glm::uvec3& dims, ShFitStats* stats, double ridge) {
    ShProbeGrid g;
    g.dims = glm::max(dims, glm::uvec3(2));
    g.lower = lower;
    g.upper = upper;
    const size_t K = g.probeCount() * 9, n = samples.size();
    // Per sample: 8 probes, 8 weights, 9 basis values (the 72 non-zeros of its row of A).
    std::vector<size_t> idx(n * 8);
    std::vector<float> w(n * 8), y(n * 9);
    for (size_t s = 0; s < n; ++s) {
        corners(g, samples[s].position, &idx[s * 8], &w[s * 8]);
        shBasis(samples[s].wo, &y[s * 9]);
    }
    auto applyA = [&](const std::vector<double>& x, std::vector<double>& out) {  // out = A x (one per sample)
        out.assign(n, 0.0);
        for (size_t s = 0; s < n; ++s) {
            double v = 0.0;
            for (int c = 0; c < 8; ++c) {
                const double* xc = &x[idx[s * 8 + size_t(c)] * 9];
                double t = 0.0;
                for (int i = 0; i < 9; ++i) t += xc[i] * double(y[s * 9 + size_t(i)]);
                v += double(w[s * 8 + size_t(c)]) * t;
            }
            out[s] = v;
        }
    };
    auto applyAt = [&](const std::vector<double>& r, std::vector<double>& out) {  // out = A^T r
        out.assign(K, 0.0);
        for (size_t s = 0; s < n; ++s)
            for (int c = 0; c < 8; ++c) {
                double* oc = &out[idx[s * 8 + size_t(c)] * 9];
                double a = double(w[s * 8 + size_t(c)]) * r[s];
                for (int i = 0; i < 9; ++i) oc[i] += a * double(y[s * 9 + size_t(i)]);
            }
    };
    // Diagonal of A^T A (Jacobi preconditioner) and the ridge, relative to its mean.
    std::vector<double> diag(K, 0.0);
    for (size_t s = 0; s < n; ++s)
        for (int c = 0; c < 8; ++c)
            for (int i = 0; i < 9; ++i) {
                double a = double(w[s * 8 + size_t(c)]) * double(y[s * 9 + size_t(i)]);
                diag[idx[s * 8 + size_t(c)] * 9 + size_t(i)] += a * a;
            }
    double meanDiag = 0.0;
    for (double d : diag) meanDiag += d;
    meanDiag = K > 0 ? meanDiag / double(K) : 0.0;
    const double lambda = std::max(ridge * meanDiag, 1e-12);
    std::vector<double> precond(K);
    for (size_t k = 0; k < K; ++k) precond[k] = 1.0 / (diag[k] + lambda);

    g.coeffs.assign(g.probeCount() * 27, 0.0f);
    ShFitStats st;
    std::vector<double> b(n), rhs, x, r, z, p, q, Ap, tmp;
    for (int ch = 0; ch < 3; ++ch) {
        for (size_t s = 0; s < n; ++s) b[s] = double(samples[s].radiance[ch]);
        applyAt(b, rhs);
        double rhsNorm = 0.0;
        for (double v : rhs) rhsNorm += v * v;
        rhsNorm = std::sqrt(rhsNorm);
        x.assign(K, 0.0);
        r = rhs;
        z.resize(K);
        for (size_t k = 0; k < K; ++k) z[k] = precond[k] * r[k];
        p = z;
        double rz = 0.0;
        for (size_t k = 0; k < K; ++k) rz += r[k] * z[k];
        int it = 0;
        double residual = rhsNorm > 0.0 ? 1.0 : 0.0;
        for (; it < 2000 && residual > 1e-7; ++it) {
            applyA(p, tmp);
            applyAt(tmp, Ap);
            double pAp = 0.0;
            for (size_t k = 0; k < K; ++k) {
                Ap[k] += lambda * p[k];
                pAp += p[k] * Ap[k];
            }
            if (!(pAp > 0.0)) break;
            double alpha = rz / pAp, rr = 0.0;
            for (size_t k = 0; k < K; ++k) {
                x[k] += alpha * p[k];
                r[k] -= alpha * Ap[k];
                rr += r[k] * r[k];
            }
            residual = std::sqrt(rr) / rhsNorm;
            double rzNext = 0.0;
            for (size_t k = 0; k < K; ++k) {
                z[k] = precond[k] * r[k];
                rzNext += r[k] * z[k];
            }
            double beta = rzNext / rz;
            rz = rzNext;
            for (size_t k = 0; k < K; ++k) p[k] = z[k] + beta * p[k];
        }
        st.iterations = std::max(st.iterations, it);
        st.relativeResidual = std::max(st.relativeResidual, residual);
        for (size_t probe = 0; probe < g.probeCount(); ++probe)
            for (int i = 0; i < 9; ++i) {
                double v = x[probe * 9 + size_t(i)];
                float f = std::isfinite(v) ? float(std::clamp(v, -65504.0, 65504.0)) : 0.0f;
                g.coeffs[probe * 27 + size_t(ch) * 9 + size_t(i)] = format::halfToFloat(format::floatToHalf(f));
            }
    }
    double rel = 0.0;
    for (const TrainingSample& s : samples) {
        glm::vec3 L = g.evaluate(s.position, s.wo);
        for (int ch = 0; ch < 3; ++ch) {
            double d = double(L[ch]) - double(s.radiance[ch]);
            rel += d * d / (double(s.radiance[ch]) * double(s.radiance[ch]) + 0.01);
        }
    }
    st.trainRelMse = n > 0 ? rel / double(3 * n) : 0.0;
    if (stats) *stats = st;
    return g;
}

}  // namespace nrad
