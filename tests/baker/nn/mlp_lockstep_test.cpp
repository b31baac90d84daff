// The lockstep training step (baker/nn/mlp_lockstep.h) against a plain scalar step of one network written here
// from the formulas, bit for bit: every lane, whatever the other lanes do (different counts, resting lanes,
// rates, penalties, losses), on every kernel this machine runs (plain 8 and 16 lanes, AVX2, AVX-512).
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <vector>

#include <gtest/gtest.h>

#include "baker/nn/mlp_lockstep.h"
#include "baker/nn/random.h"

namespace nrad {
namespace {

// One mini-batch step of one network: forward (fused multiply-adds from the bias up), the regression loss's
// gradient, backpropagation, the batch's summed gradient / count, the L2 penalty, Adam.
void referenceStep(const NetworkShape& s, std::vector<float>& p, std::vector<float>& m, std::vector<float>& v,
                   const std::vector<const float*>& rows, float rate, float decay, float c1, float c2, LossKind loss) {
    const size_t L = s.hidden.size() + 1;
    auto width = [&](size_t l) { return l == 0 ? s.inputs : l <= s.hidden.size() ? s.hidden[l - 1] : s.outputs; };
    std::vector<size_t> off;
    size_t at = 0;
    for (size_t l = 0; l < L; ++l) {
        off.push_back(at);
        at += size_t(width(l + 1)) * size_t(width(l) + 1);
    }
    std::vector<float> grad(p.size(), 0.0f);
    for (const float* row : rows) {
        std::vector<std::vector<float>> a(L + 1), d(L + 1);
        a[0].assign(row, row + s.inputs);
        for (size_t l = 0; l < L; ++l) {
            const int in = width(l), out = width(l + 1);
            for (int o = 0; o < out; ++o) {
                float acc = p[off[l] + size_t(out * in + o)];
                for (int i = 0; i < in; ++i) acc = std::fma(p[off[l] + size_t(o * in + i)], a[l][size_t(i)], acc);
                a[l + 1].push_back(l + 1 == L || acc > 0.0f ? acc : 0.0f);
            }
        }
        const std::vector<float>& y = a[L];
        float w = 1.0f;
        if (loss == LossKind::RelativeL2) {
            const float lum = 0.2126f * std::max(0.0f, y[0]) + 0.7152f * std::max(0.0f, y[1]) + 0.0722f * std::max(0.0f, y[2]);
            w = 1.0f / (lum * lum + 0.01f);
        } else if (loss == LossKind::SymmetricRelativeL2) {
            const float lum = 0.2126f * std::max(0.0f, y[0]) + 0.7152f * std::max(0.0f, y[1]) + 0.0722f * std::max(0.0f, y[2]);
            const float t = 0.2126f * std::max(0.0f, row[kPackedTarget]) + 0.7152f * std::max(0.0f, row[kPackedTarget + 1]) +
                            0.0722f * std::max(0.0f, row[kPackedTarget + 2]);
            w = 1.0f / (0.5f * (lum * lum + t * t) + 0.01f);
        }
        if (loss == LossKind::SymmetricRelativeExp) {  // loss.cpp's regressionGradient, the reference's own
            const float yy[3] = {y[0], y[1], y[2]}, tt[3] = {row[kPackedTarget], row[kPackedTarget + 1], row[kPackedTarget + 2]};
            const float ww[3] = {row[kPackedWeight], row[kPackedWeight + 1], row[kPackedWeight + 2]};
            float g[3];
            regressionGradient(loss, yy, tt, ww, g);
            d[L].assign(g, g + 3);
        } else {
            for (int c = 0; c < 3; ++c) d[L].push_back(2.0f * w * row[kPackedWeight + c] * (y[size_t(c)] - row[kPackedTarget + c]));
        }
        for (size_t l = L - 1; l >= 1; --l) {
            const int in = width(l), out = width(l + 1);
            for (int i = 0; i < in; ++i) {
                float acc = 0.0f;
                for (int o = 0; o < out; ++o) acc = std::fma(p[off[l] + size_t(o * in + i)], d[l + 1][size_t(o)], acc);
                d[l].push_back(a[l][size_t(i)] > 0.0f ? acc : 0.0f);
            }
        }
        for (size_t l = 0; l < L; ++l) {
            const int in = width(l), out = width(l + 1);
            for (int o = 0; o < out; ++o) {
                for (int i = 0; i < in; ++i) {
                    float& g = grad[off[l] + size_t(o * in + i)];
                    g = std::fma(d[l + 1][size_t(o)], a[l][size_t(i)], g);
                }
                grad[off[l] + size_t(out * in + o)] += d[l + 1][size_t(o)];
            }
        }
    }
    const float inv = 1.0f / float(rows.size());
    const AdamRates r = adamRates(rate, c1, c2);
    for (size_t q = 0; q < p.size(); ++q) {
        float g = grad[q] * inv;
        if (decay > 0.0f && q + size_t(s.outputs) < p.size()) g += decay * p[q];
        m[q] = kAdamBeta1 * m[q] + (1.0f - kAdamBeta1) * g;
        v[q] = kAdamBeta2 * v[q] + (1.0f - kAdamBeta2) * g * g;
        p[q] -= r.rate * m[q] / (std::sqrt(v[q]) + r.epsilon);
    }
}

// The kernel's lanes trained together for a few steps against as many networks trained alone; returns how many
// parameters (and moments) differed in their bits.
size_t mismatches(const NetworkShape& shape, LossKind loss, const LockstepKernel& kernel) {
    const int lanesN = kernel.lanes;
    const size_t laneCount = static_cast<size_t>(lanesN);
    SplitMix64 rng(23);
    std::vector<float> samples(200 * kPackedFloats);
    for (size_t i = 0; i < samples.size(); ++i) {
        const int q = int(i % kPackedFloats);
        samples[i] = q < kPackedTarget ? 2.0f * rng.uniform() - 1.0f : q < kPackedWeight ? 3.0f * rng.uniform() : q < 15 ? rng.uniform() : 0.0f;
    }
    LockstepNetworks nets(shape, lanesN);
    std::vector<std::vector<float>> p(laneCount), m(p), v(p);
    for (int j = 0; j < lanesN; ++j) {
        Mlp mlp(shape);
        mlp.initialize(uint64_t(j) + 5, 0.5f);
        p[size_t(j)] = mlp.parameters();
        m[size_t(j)].assign(p[size_t(j)].size(), 0.0f);
        v[size_t(j)].assign(p[size_t(j)].size(), 0.0f);
        nets.setLane(j, p[size_t(j)]);
    }
    LockstepWorkspace ws;
    int t[kMaxLockstepLanes] = {};
    for (int stepIndex = 0; stepIndex < 6; ++stepIndex) {
        LockstepLane lanes[kMaxLockstepLanes];
        std::vector<std::vector<const float*>> rows(laneCount);
        for (int j = 0; j < lanesN; ++j) {
            // Lanes 3 and 12 rest on even steps, lane 5 always; the others take 1 to 64 samples.
            const bool rests = ((j == 3 || j == 12) && stepIndex % 2 == 0) || j == 5;
            const int count = rests ? 0 : 1 + int(rng.below(64));
            for (int k = 0; k < count; ++k) rows[size_t(j)].push_back(&samples[size_t(rng.below(200)) * kPackedFloats]);
            LockstepLane& lane = lanes[j];
            lane.count = count;
            std::copy(rows[size_t(j)].begin(), rows[size_t(j)].end(), lane.rows);
            lane.learningRate = 0.01f * float(j + 1);
            lane.weightDecay = j % 2 ? 0.003f * float(j) : 0.0f;
            if (count > 0) ++t[j];
            lane.c1 = float(1.0 - std::pow(double(kAdamBeta1), t[j]));
            lane.c2 = float(1.0 - std::pow(double(kAdamBeta2), t[j]));
            if (count > 0)
                referenceStep(shape, p[size_t(j)], m[size_t(j)], v[size_t(j)], rows[size_t(j)], lane.learningRate, lane.weightDecay,
                              lane.c1, lane.c2, loss);
        }
        kernel.step(nets, lanes, loss, ws);
    }
    size_t bad = 0;
    for (int j = 0; j < lanesN; ++j)
        for (size_t q = 0; q < p[size_t(j)].size(); ++q) {
            const size_t at = q * laneCount + size_t(j);
            bad += std::memcmp(&nets.params[at], &p[size_t(j)][q], 4) != 0;
            bad += std::memcmp(&nets.m[at], &m[size_t(j)][q], 4) != 0;
            bad += std::memcmp(&nets.v[at], &v[size_t(j)][q], 4) != 0;
        }
    return bad;
}

std::vector<NetworkShape> shapes() {
    std::vector<NetworkShape> out;
    for (std::vector<int> hidden : {std::vector<int>{9}, std::vector<int>{16}, std::vector<int>{5, 7}, std::vector<int>{16, 16}}) {
        NetworkShape s;
        s.hidden = hidden;
        out.push_back(s);
    }
    return out;
}

TEST(MlpLockstep, EveryLaneIsItsNetworkTrainedAloneBitForBit) {
    const std::vector<LockstepKernel> kernels = lockstepKernels();
    for (const LockstepKernel& k : kernels) std::printf("lockstep kernel %s (%d lanes)\n", k.name, k.lanes);
    for (const NetworkShape& s : shapes())
        for (LossKind loss : {LossKind::RelativeL2, LossKind::SymmetricRelativeL2, LossKind::L2, LossKind::SymmetricRelativeExp})
            for (const LockstepKernel& k : kernels)
                EXPECT_EQ(mismatches(s, loss, k), 0u) << k.name << ", " << s.hidden.size() << " hidden layers, " << lossName(loss);
}

TEST(MlpLockstep, TheChosenKernelIsTheWidestThisCpuRuns) {
    const std::vector<LockstepKernel>& kernels = lockstepKernels();
    ASSERT_GE(kernels.size(), 2u);
    EXPECT_STREQ(kernels[0].name, "plain");
    EXPECT_STREQ(kernels[1].name, "plain16");
    const char* forced = std::getenv("NRAD_TRAIN_KERNEL");
    if (forced && *forced) GTEST_SKIP() << "NRAD_TRAIN_KERNEL=" << forced;
    const char* widest = kernels.size() > 2 ? kernels.back().name : "plain";
    EXPECT_STREQ(lockstepKernel().name, widest);
#if defined(__x86_64__)
    __builtin_cpu_init();
    if (__builtin_cpu_supports("avx512f")) {
        EXPECT_STREQ(lockstepKernel().name, "avx512");
        EXPECT_EQ(lockstepKernel().lanes, 16);
    }
    if (__builtin_cpu_supports("avx2") && __builtin_cpu_supports("fma")) {
        EXPECT_STREQ(lockstepKernel(8).name, "avx2");
    }
#elif defined(__aarch64__)
    EXPECT_STREQ(lockstepKernel(8).name, "neon");
#else
    EXPECT_STREQ(lockstepKernel(8).name, "plain");
#endif
}

}  // namespace
}  // namespace nrad
