// baker/nn and the trainer built on it: backpropagation against finite differences, the light selector's
// padded network against the plain one on the same weights, the losses' gradients against finite
// differences, Adam and the schedules, the shuffles' remainder by a multiply against the division's, deterministic
// initialisation, and the trainer reproducing a known function of (position, normal, direction) to a stated error.
#include "baker/nn/mlp.h"

#include <cmath>
#include <cstdint>
#include <vector>

#include <gtest/gtest.h>
#include <tbb/task_arena.h>

#include "baker/nn/adam.h"
#include "baker/nn/loss.h"
#include "baker/nn/padded_mlp.h"
#include "baker/nn/random.h"
#include "baker/nn/schedule.h"

#include "baker/bake/trainer.h"

namespace nrad {
namespace {

TEST(Mlp, BackpropagationMatchesFiniteDifferences) {
    for (std::vector<int> hidden : {std::vector<int>{9}, std::vector<int>{7, 5}}) {
        NetworkShape shape;
        shape.hidden = hidden;
        Mlp mlp(shape);
        mlp.initialize(42, 0.3f);
        const float x[9] = {0.3f, -0.7f, 0.1f, 0.0f, 1.0f, 0.0f, 0.6f, 0.0f, 0.8f};
        const float target[3] = {0.5f, -0.2f, 1.0f};
        MlpWorkspace ws;
        float y[3];
        auto loss = [&]() {
            mlp.forward(x, y, ws);
            double l = 0.0;
            for (int c = 0; c < 3; ++c) l += double(y[c] - target[c]) * double(y[c] - target[c]);
            return l;
        };
        loss();
        float dy[3];
        for (int c = 0; c < 3; ++c) dy[c] = 2.0f * (y[c] - target[c]);
        std::vector<float> grad(mlp.parameters().size(), 0.0f);
        mlp.backward(dy, ws, grad.data());
        for (size_t i = 0; i < grad.size(); ++i) {
            float saved = mlp.parameters()[i];
            const float h = 1e-3f;
            mlp.parameters()[i] = saved + h;
            double up = loss();
            mlp.parameters()[i] = saved - h;
            double down = loss();
            mlp.parameters()[i] = saved;
            double numeric = (up - down) / (2.0 * h);
            EXPECT_NEAR(grad[i], numeric, 2e-3 * std::max(1.0, std::abs(numeric))) << "parameter " << i;
        }
    }
}

// The light selector's network and the plain Mlp are one function: on the same weights (the padded
// input-major layout converted to the asset's row-major one) they give the same logits and the same gradient.
TEST(PaddedMlp, AgreesWithThePlainNetworkOnTheSameWeights) {
    for (int outputs : {3, 17, 40, 64}) {
        PaddedMlp padded(outputs, 99);
        // Give the output layer and biases full-size values (initialisation keeps them small).
        SplitMix64 rng(5);
        std::vector<float>& pp = padded.parameters();
        const std::vector<float> layout = padded.toRowMajor(std::vector<float>(pp.size(), 1.0f));
        for (size_t i = 0; i < pp.size(); ++i)
            if (pp[i] != 0.0f || i < size_t(9 * 64)) pp[i] = 0.3f * (2.0f * rng.uniform() - 1.0f);
        NetworkShape shape;
        shape.hidden = {64, 64};
        shape.outputs = outputs;
        Mlp plain(shape);
        ASSERT_EQ(plain.parameters().size(), layout.size());
        plain.parameters() = padded.toRowMajor(pp);
        for (int trial = 0; trial < 20; ++trial) {
            float x[9];
            for (float& v : x) v = 2.0f * rng.uniform() - 1.0f;
            PaddedMlp::Activations a;
            padded.forward(x, a);
            std::vector<float> y(static_cast<size_t>(outputs));
            MlpWorkspace ws;
            plain.forward(x, y.data(), ws);
            for (int o = 0; o < outputs; ++o) ASSERT_NEAR(a.logits[o], y[size_t(o)], 1e-5f * std::max(1.0f, std::abs(y[size_t(o)])));
            float dLogits[PaddedMlp::kMaxOutputs] = {};
            for (int o = 0; o < outputs; ++o) dLogits[o] = 2.0f * rng.uniform() - 1.0f;
            std::vector<float> gp(pp.size(), 0.0f), gq(plain.parameters().size(), 0.0f);
            padded.backward(x, a, dLogits, gp.data());
            plain.backward(dLogits, ws, gq.data());
            const std::vector<float> g = padded.toRowMajor(gp);
            for (size_t i = 0; i < g.size(); ++i) ASSERT_NEAR(g[i], gq[i], 1e-5f * std::max(1.0f, std::abs(gq[i]))) << "parameter " << i;
        }
    }
}

// The mini-batch kernels against the plain pass sample by sample: outputs bit for bit (the same sums),
// gradients to 1e-5 (only the order of the sum over the batch differs), for batch sizes that do and do not
// fill the kernels' lanes and shapes of one and two hidden layers.
TEST(Mlp, BatchKernelsAgreeWithThePlainPass) {
    for (std::vector<int> hidden : {std::vector<int>{9}, std::vector<int>{16, 7}}) {
        NetworkShape shape;
        shape.hidden = hidden;
        Mlp mlp(shape);
        mlp.initialize(11, 0.2f);
        SplitMix64 rng(17);
        for (int count : {1, 5, 8, 32, 64}) {
            std::vector<float> x(size_t(count) * 9), dy(size_t(count) * 3);
            for (float& v : x) v = 2.0f * rng.uniform() - 1.0f;
            for (float& v : dy) v = 2.0f * rng.uniform() - 1.0f;
            MlpBatchWorkspace bws;
            mlp.forwardBatch(x.data(), count, bws);
            const size_t last = mlp.layers();
            for (int k = 0; k < count; ++k)
                for (int c = 0; c < 3; ++c) bws.delta(last, c)[k] = dy[size_t(k) * 3 + size_t(c)];
            std::vector<float> gBatch(mlp.parameters().size(), 0.0f), gPlain(mlp.parameters().size(), 0.0f);
            mlp.backwardBatch(bws, gBatch.data());
            MlpWorkspace ws;
            for (int k = 0; k < count; ++k) {
                float y[3];
                mlp.forward(&x[size_t(k) * 9], y, ws);
                for (int c = 0; c < 3; ++c) ASSERT_EQ(bws.value(last, c)[k], y[c]) << "sample " << k << " of " << count;
                mlp.backward(&dy[size_t(k) * 3], ws, gPlain.data());
            }
            for (size_t i = 0; i < gPlain.size(); ++i)
                ASSERT_NEAR(gBatch[i], gPlain[i], 1e-5f * std::max(1.0f, std::abs(gPlain[i]))) << "parameter " << i << ", batch " << count;
        }
    }
}

TEST(Loss, RegressionGradientsMatchFiniteDifferences) {
    const float t[3] = {0.7f, 1.3f, 0.2f}, w[3] = {1.0f, 0.5f, 2.0f};
    for (LossKind loss : {LossKind::L2, LossKind::Log, LossKind::RelativeL2, LossKind::SymmetricRelativeL2}) {
        float y[3] = {0.9f, 1.0f, 0.6f}, dy[3];
        regressionGradient(loss, y, t, w, dy);
        // The relative losses hold their weight constant: 1 / (lum(y)^2 + 0.01) (the prediction's luminance), and
        // the symmetric one 1 / ((lum(y)^2 + lum(t)^2) / 2 + 0.01).
        const double l = 0.2126 * y[0] + 0.7152 * y[1] + 0.0722 * y[2], m = 0.2126 * t[0] + 0.7152 * t[1] + 0.0722 * t[2];
        const double scale = loss == LossKind::RelativeL2            ? 1.0 / (l * l + 0.01)
                             : loss == LossKind::SymmetricRelativeL2 ? 1.0 / (0.5 * (l * l + m * m) + 0.01)
                                                                     : 1.0;
        for (int c = 0; c < 3; ++c) {
            auto value = [&](float v) {
                double e = 0.0;
                for (int k = 0; k < 3; ++k) {
                    const double d = double(k == c ? v : y[k]) - t[k];
                    e += scale * w[k] * d * d;
                }
                return e;
            };
            const double numeric = (value(y[c] + 1e-3f) - value(y[c] - 1e-3f)) / 2e-3;
            EXPECT_NEAR(dy[c], numeric, 1e-3 * std::max(1.0, std::abs(numeric))) << lossName(loss) << " channel " << c;
        }
    }
    {
        // The exponential one: the symmetric loss of p = exp(y) - 1 against the linear target, its weight
        // 1 / ((lum(p)^2 + lum(t)^2) / 2 + 1) held constant (the floor 0.01 / kExpScaleFraction^2 = 1).
        const LossKind loss = LossKind::SymmetricRelativeExp;
        const float y[3] = {0.9f, -0.2f, 1.6f};
        float dy[3];
        regressionGradient(loss, y, t, w, dy);
        double p[3], l = 0.0;
        for (int k = 0; k < 3; ++k) p[k] = std::expm1(double(y[k]));
        l = 0.2126 * p[0] + 0.0722 * p[2];  // p[1] < 0 counts as 0
        const double m = 0.2126 * t[0] + 0.7152 * t[1] + 0.0722 * t[2], scale = 1.0 / (0.5 * (l * l + m * m) + 1.0);
        for (int c = 0; c < 3; ++c) {
            auto value = [&](double v) {
                double e = 0.0;
                for (int k = 0; k < 3; ++k) {
                    const double d = std::expm1(k == c ? v : double(y[k])) - t[k];
                    e += scale * w[k] * d * d;
                }
                return e;
            };
            const double numeric = (value(y[c] + 1e-4) - value(y[c] - 1e-4)) / 2e-4;
            EXPECT_NEAR(dy[c], numeric, 1e-4 * std::max(1.0, std::abs(numeric))) << lossName(loss) << " channel " << c;
        }
        // Its scale is a tenth of the mean, and a network starts at the mean: exp(b) - 1 = 10.
        EXPECT_TRUE(exponentialOutput(loss));
        EXPECT_FALSE(exponentialOutput(LossKind::SymmetricRelativeL2));
        EXPECT_FLOAT_EQ(scaleFraction(loss), 0.1f);
        EXPECT_NEAR(std::expm1(double(initialOutputBias(loss))), 10.0, 1e-5);
        EXPECT_FLOAT_EQ(lossTarget(loss, 0.5f, 3.0f), 1.5f);
    }
    // Targets in the output space: divided by the scale, through log1p for the log loss.
    EXPECT_FLOAT_EQ(lossTarget(LossKind::L2, 0.5f, 3.0f), 1.5f);
    EXPECT_FLOAT_EQ(lossTarget(LossKind::Log, 0.5f, 3.0f), std::log1p(1.5f));
}

TEST(Loss, CrossEntropyGradientMatchesFiniteDifferences) {
    const float logits[5] = {0.3f, -1.2f, 2.0f, 0.0f, 0.7f};
    const uint64_t mask = 0b11011;  // group 2 is not a candidate
    float d[5];
    crossEntropyGradient(logits, 5, mask, 3, 0.8f, d);
    EXPECT_EQ(d[2], 0.0f);
    for (int g = 0; g < 5; ++g) {
        if (!(mask >> g & 1u)) continue;
        auto value = [&](float v) {
            float l[5], q[5];
            std::copy(logits, logits + 5, l);
            l[g] = v;
            maskedSoftmax(l, 5, mask, q);
            return -0.8 * std::log(double(q[3]));
        };
        const double numeric = (value(logits[g] + 1e-3f) - value(logits[g] - 1e-3f)) / 2e-3;
        EXPECT_NEAR(d[g], numeric, 1e-3) << "group " << g;
    }
    float q[5];
    maskedSoftmax(logits, 5, mask, q);
    EXPECT_NEAR(q[0] + q[1] + q[3] + q[4], 1.0f, 1e-6f);
    EXPECT_EQ(q[2], 0.0f);
}

TEST(Adam, StepsByTheLearningRateAndFindsTheMinimum) {
    // The first step moves every parameter by the learning rate against its gradient's sign (bias
    // correction); a quadratic's minimum is then found.
    std::vector<float> p = {1.0f, -2.0f, 0.5f};
    Adam adam(p.size());
    adam.step(p, {4.0f, -0.001f, 0.0f}, 0.1f);
    EXPECT_NEAR(p[0], 0.9f, 1e-5f);
    EXPECT_NEAR(p[1], -1.9f, 1e-4f);
    EXPECT_EQ(p[2], 0.5f);
    const float target[3] = {0.25f, -0.5f, 2.0f};
    for (int i = 0; i < 3000; ++i) {
        std::vector<float> g(3);
        for (int k = 0; k < 3; ++k) g[size_t(k)] = 2.0f * (p[size_t(k)] - target[k]);
        adam.step(p, g, exponentialDecay(0.05f, 0.01f, float(i) / 3000.0f));
    }
    for (int k = 0; k < 3; ++k) EXPECT_NEAR(p[size_t(k)], target[k], 1e-3f);
    // The moving average of the parameters: decay 0.5 halves the distance each update.
    std::vector<float> avg = {0.0f};
    updateAverage(avg, {1.0f}, 0.5f);
    updateAverage(avg, {1.0f}, 0.5f);
    EXPECT_FLOAT_EQ(avg[0], 0.75f);
}

TEST(Schedule, EndPoints) {
    EXPECT_FLOAT_EQ(exponentialDecay(0.01f, 0.1f, 0.0f), 0.01f);
    EXPECT_FLOAT_EQ(exponentialDecay(0.01f, 0.1f, 1.0f), 0.001f);
    EXPECT_FLOAT_EQ(exponentialDecay(0.01f, 0.1f, 0.5f), 0.01f * std::sqrt(0.1f));
    EXPECT_FLOAT_EQ(linearDecay(2.0f, 0.25f), 1.5f);
    EXPECT_EQ(linearDecay(2.0f, 1.0f), 0.0f);
    EXPECT_EQ(linearDecay(2.0f, 3.0f), 0.0f);
}

// The training's shuffles take x % n by digits and double quotients (remaindersDescending): the division's
// remainder for every x and n < 2^32, at the edges of both (n near powers of two and 2^32, x near multiples of n and
// at 2^64 - 1) and at random, on the AVX-512 path where the CPU has it and on the one-by-one path; and the draws
// are those of below() in turn.
TEST(Random, RemaindersByDigitsAreTheDivisionsRemainders) {
    std::vector<uint64_t> divisors = {1, 2, 3, 5, 7, 10, 1000, 5925, 65535, 65536, 65537, (1ull << 21) - 1, 1ull << 21,
                                      (1ull << 22) + 1, (1ull << 31) - 1, 1ull << 31, (1ull << 32) - 2, (1ull << 32) - 1};
    SplitMix64 rng(3);
    for (int k = 0; k < 2000; ++k) divisors.push_back(1 + rng.below(1u << 20));
    for (int k = 0; k < 300; ++k) divisors.push_back(1 + (rng.next() >> (32 + rng.next() % 32)));
    uint64_t checked = 0;
    for (uint64_t n : divisors) {
        ASSERT_TRUE(n >= 1 && n < (1ull << 32));
        std::vector<uint64_t> xs = {0, 1, n - 1, n, n + 1, 2 * n - 1, 2 * n, ~0ull, ~0ull - 1, ~0ull - n, (~0ull / n) * n, (~0ull / n) * n - 1,
                                    (1ull << 53) - 1, 1ull << 53, (1ull << 42) * n, (1ull << 42) * n - 1};
        for (int k = 0; k < 500; ++k) xs.push_back(rng.next());
        // Lane j divides by n + j - (count - 1) ... : every x against every lane's divisor near n.
        for (size_t first = 0; first < xs.size(); first += 8) {
            const uint32_t count = uint32_t(std::min<size_t>(xs.size() - first, std::min<uint64_t>(n, 8)));
            const uint64_t top = n - 1 + count;  // the last lane divides by n
            if (top >= (1ull << 32)) continue;
            uint32_t fast[8], plain[8];
            remaindersDescending(&xs[first], top, count, fast);
            remaindersDescendingScalar(&xs[first], top, count, plain);
            for (uint32_t k = 0; k < count; ++k) {
                ASSERT_EQ(fast[k], xs[first + k] % (top - k)) << "x " << xs[first + k] << " n " << top - k;
                ASSERT_EQ(plain[k], xs[first + k] % (top - k)) << "x " << xs[first + k] << " n " << top - k;
                ++checked;
            }
        }
    }
    EXPECT_GT(checked, 700000u);
    // The shuffle's draws: below(top), below(top - 1), ... in turn, for blocks of any length.
    for (uint64_t top : {2ull, 9ull, 64ull, 65ull, 1000ull, 5925ull, (1ull << 32) - 1}) {
        for (uint32_t count : {1u, 7u, 8u, 9u, 63u, 64u, 65u, 200u}) {
            if (count > top - 1) continue;
            SplitMix64 a(top * 31 + count), b(top * 31 + count);
            std::vector<uint32_t> drawn(count);
            drawBelowDescending(a, top, count, drawn.data());
            for (uint32_t k = 0; k < count; ++k) ASSERT_EQ(drawn[k], b.below(top - k)) << "top " << top << " draw " << k;
            EXPECT_EQ(a.next(), b.next());
        }
    }
}

TEST(Mlp, InitialisationIsDeterministic) {
    Mlp a(NetworkShape{}), b(NetworkShape{}), c(NetworkShape{});
    a.initialize(7, 1.0f);
    b.initialize(7, 1.0f);
    c.initialize(8, 1.0f);
    EXPECT_EQ(a.parameters(), b.parameters());
    EXPECT_NE(a.parameters(), c.parameters());
    EXPECT_EQ(a.parameters().size(), 120u);
}

// Known targets: `representable` is a sum of ReLUs of linear forms of the inputs (five hidden units), so a
// 9-9-3 network can match it exactly; `smooth` has a product of inputs (n.w), which it can only approximate.
float relu(float x) { return std::max(0.0f, x); }
glm::vec3 representable(const glm::vec3& q, const glm::vec3& n, const glm::vec3& w) {
    float a = relu(q.x), b = relu(0.5f - q.y), c = relu(w.z), d = relu(n.x + w.x), e = relu(q.z - n.y);
    return glm::vec3(1.0f + 0.4f * a + 0.3f * b + 0.5f * c, 0.8f + 0.2f * d + 0.3f * e, 0.5f + 0.6f * c + 0.1f * a);
}
glm::vec3 smooth(const glm::vec3& q, const glm::vec3& n, const glm::vec3& w) {
    float base = 1.0f + 0.4f * q.x - 0.3f * q.y + 0.2f * q.z + 0.5f * std::max(0.0f, glm::dot(n, w));
    return glm::vec3(base, 0.8f * base + 0.1f * w.y, 0.5f * base + 0.2f * n.z);
}

template <typename F>
std::vector<TrainingSample> makeSamples(const VoxelGrid& grid, F f, size_t count) {
    SplitMix64 rng(3);
    std::vector<TrainingSample> samples(count);
    for (TrainingSample& s : samples) {
        s.position = glm::vec3(rng.uniform(), rng.uniform(), rng.uniform());
        float a = 6.2831853f * rng.uniform(), z = 2.0f * rng.uniform() - 1.0f, r = std::sqrt(1.0f - z * z);
        s.normal = glm::vec3(r * std::cos(a), r * std::sin(a), z);
        a = 6.2831853f * rng.uniform();
        z = rng.uniform();
        r = std::sqrt(1.0f - z * z);
        s.wo = Frame::fromNormal(s.normal).toWorld(glm::vec3(r * std::cos(a), r * std::sin(a), z));
        s.radiance = f(grid.positionInVoxel(s.position, 0), s.normal, s.wo);
        s.voxel = 0;
    }
    return samples;
}

// One voxel over the unit cube.
VoxelGrid unitVoxel() {
    Bounds3 bounds;
    bounds.extend(glm::vec3(0.0f));
    bounds.extend(glm::vec3(1.0f));
    return VoxelGrid(bounds, glm::uvec3(1));
}

std::vector<const TrainingSample*> pointersTo(const std::vector<TrainingSample>& samples) {
    std::vector<const TrainingSample*> ptrs;
    for (const TrainingSample& s : samples) ptrs.push_back(&s);
    return ptrs;
}

TEST(Trainer, ReproducesKnownFunctions) {
    Bounds3 bounds;
    bounds.extend(glm::vec3(0.0f));
    bounds.extend(glm::vec3(1.0f));
    VoxelGrid grid(bounds, glm::uvec3(1));
    std::vector<TrainingSample> exact = makeSamples(grid, representable, 3000);
    std::vector<TrainingSample> approx = makeSamples(grid, smooth, 3000);
    for (LossKind loss : {LossKind::L2, LossKind::RelativeL2, LossKind::SymmetricRelativeL2, LossKind::Log, LossKind::SymmetricRelativeExp}) {
        TrainSettings settings;
        settings.loss = loss;
        settings.epochs = 600;
        for (int which = 0; which < 2; ++which) {
            std::vector<const TrainingSample*> ptrs;
            for (const TrainingSample& s : which == 0 ? exact : approx) ptrs.push_back(&s);
            VoxelTrainResult r = trainVoxel(grid, 0, ptrs, settings);
            EXPECT_FALSE(r.fallback);
            EXPECT_GT(r.heldOutCount, 200u);
            for (float p : r.params) ASSERT_TRUE(std::isfinite(p));
            // Stated bounds on the held-out relMSE. Exactly representable: 2e-4 (1.4% RMS) with the linear
            // output; the log-space network's exp() output cannot be exact, so 2e-3. The smooth function: 1e-2.
            double bound = which == 1 ? 1e-2 : (exponentialOutput(loss) ? 2e-3 : 2e-4);
            EXPECT_LT(r.heldOutRelMse, bound) << lossName(loss) << (which == 0 ? " representable" : " smooth");
        }
    }
}

// Restarts (TrainSettings::restarts): the first initialisation is the one a single training uses, bit for bit,
// and of several the lowest held-out error is kept, so it is never above the single training's; a smooth
// function with few samples and short training, where initialisations differ, shows that they do.
TEST(Trainer, RestartsKeepTheLowestHeldOutErrorAndStartFromTheSingleTraining) {
    const VoxelGrid grid = unitVoxel();
    const std::vector<TrainingSample> samples = makeSamples(grid, smooth, 400);
    const std::vector<const TrainingSample*> ptrs = pointersTo(samples);
    TrainSettings settings;
    settings.epochs = 60;
    settings.weightDecays = {0.0f};
    settings.restarts = 1;  // (the default is 3)
    settings.raceEpochs = 0;
    const VoxelTrainResult one = trainVoxel(grid, 0, ptrs, settings);
    settings.restarts = 4;
    const VoxelTrainResult four = trainVoxel(grid, 0, ptrs, settings);
    EXPECT_LE(four.heldOutRelMse, one.heldOutRelMse);
    EXPECT_NE(four.params, one.params) << "four initialisations, and the first won: they do not differ here";
    // The kept one is a training from one of the restarts: the same restart alone gives the same network.
    bool found = false;
    for (int r = 1; r < 4 && !found; ++r) {
        TrainSettings only = settings;
        only.restarts = r + 1;
        found = trainVoxel(grid, 0, ptrs, only).params == four.params;
    }
    EXPECT_TRUE(found);
}

// Many voxels trained at once (trainVoxels: every training a lane of networks in lockstep, eight to a group, the
// groups on the arena's threads) give each voxel what it gets trained alone, bit for bit, on 1 and 2 threads:
// voxels of different sizes, so that lanes end their epochs, attempts and trainings at different steps.
TEST(Trainer, VoxelsTrainedTogetherAreEachTrainedAloneBitForBit) {
    const VoxelGrid grid = unitVoxel();
    std::vector<std::vector<TrainingSample>> samples;
    std::vector<std::vector<VoxelSample>> entries;
    for (int v = 0; v < 11; ++v) samples.push_back(makeSamples(grid, v % 2 ? smooth : representable, 40 + 37 * v));
    for (const std::vector<TrainingSample>& set : samples) {
        entries.emplace_back();
        for (const TrainingSample& s : set) entries.back().push_back({&s, 1.0f, grid.positionInVoxel(s.position, 0)});
    }
    TrainSettings settings;
    settings.restarts = 2;  // with the two weight decays: 44 trainings
    std::vector<uint32_t> ids;
    std::vector<const std::vector<VoxelSample>*> sets;
    for (size_t v = 0; v < entries.size(); ++v) {
        ids.push_back(uint32_t(v));
        sets.push_back(&entries[v]);
    }
    // Every candidate to its end, and a race after 10 epochs (the winners paused, resumed in whatever lane is free)
    // within each weight decay's starts and among all four candidates; the parameters themselves judged
    // each epoch, and their epoch average (the default).
    struct Case {
        int race;
        float average;
        bool all;
    };
    for (const auto& [race, average, all] : {Case{0, 0.0f, false}, Case{10, 0.0f, false}, Case{10, 0.0f, true}, Case{0, 0.9f, false},
                                            Case{10, 0.9f, false}, Case{10, 0.9f, true}}) {
        settings.raceEpochs = race;
        settings.raceAll = all;
        settings.epochAverage = average;
        // The average's error falls more smoothly: longer and less patient, so that some stop early.
        settings.epochs = average > 0.0f ? 200 : 60;
        settings.patience = average > 0.0f ? 1 : 3;
        std::vector<VoxelTrainResult> alone;
        for (size_t v = 0; v < entries.size(); ++v) alone.push_back(trainVoxel(uint32_t(v), entries[v], settings));
        for (int threads : {1, 2}) {
            std::vector<VoxelTrainResult> together;
            size_t done = 0;
            tbb::task_arena(threads).execute([&] { together = trainVoxels(ids, sets, settings, [&] { ++done; }); });
            ASSERT_EQ(together.size(), alone.size());
            EXPECT_EQ(done, alone.size()) << threads << " threads";
            for (size_t v = 0; v < alone.size(); ++v) {
                EXPECT_EQ(together[v].voxel, uint32_t(v));
                EXPECT_EQ(together[v].params, alone[v].params)
                    << "voxel " << v << ", " << threads << " threads, race " << race << (all ? " (all)" : "") << ", average " << average;
                EXPECT_EQ(together[v].heldOutRelMse, alone[v].heldOutRelMse);
                EXPECT_EQ(together[v].epochs, alone[v].epochs);
                EXPECT_EQ(together[v].weightDecay, alone[v].weightDecay);
            }
        }
        // The trainings end at different steps: some stop early, some run every epoch.
        const int epochs = settings.epochs;
        EXPECT_TRUE(std::any_of(alone.begin(), alone.end(), [&](const VoxelTrainResult& r) { return r.epochs < epochs; })) << average;
        EXPECT_TRUE(std::any_of(alone.begin(), alone.end(), [&](const VoxelTrainResult& r) { return r.epochs == epochs; })) << average;
    }
}

// The race among all candidates (TrainSettings::raceEpochs, raceAll): the candidate with the lowest held-out error in
// its first 20 epochs (its curve, recorded every epoch) trains on alone and ends exactly as it does trained alone to
// its end.
TEST(Trainer, RaceKeepsTheCandidateAheadAtItsEpochTrainedToItsEnd) {
    const VoxelGrid grid = unitVoxel();
    const std::vector<TrainingSample> samples = makeSamples(grid, smooth, 600);
    const std::vector<const TrainingSample*> ptrs = pointersTo(samples);
    TrainSettings settings;
    settings.epochs = 80;
    settings.patience = 80;
    settings.curveEvery = 1;
    settings.weightDecays = {0.0f, 40.0f, 400.0f};
    settings.restarts = 1;  // one start per decay (the default is 3)
    settings.raceAll = true;
    std::vector<VoxelTrainResult> alone;
    size_t ahead = 0;
    std::vector<double> atRace;
    for (float decay : settings.weightDecays) {
        TrainSettings one = settings;
        one.weightDecays = {decay};
        alone.push_back(trainVoxel(grid, 0, ptrs, one));
        double best = 1e30;
        for (const TrainCurvePoint& p : alone.back().curve)
            if (p.epoch < 20) best = std::min(best, p.heldOutRelMse);
        atRace.push_back(best);
        if (best < atRace[ahead]) ahead = atRace.size() - 1;
    }
    settings.raceEpochs = 20;
    const VoxelTrainResult raced = trainVoxel(grid, 0, ptrs, settings);
    EXPECT_EQ(raced.params, alone[ahead].params);
    EXPECT_EQ(raced.weightDecay, settings.weightDecays[ahead]);
    EXPECT_EQ(raced.epochs, alone[ahead].epochs);
    // Without the race the lowest final error wins, which is never above the race's winner's.
    settings.raceEpochs = 0;
    EXPECT_LE(trainVoxel(grid, 0, ptrs, settings).heldOutRelMse, raced.heldOutRelMse);
    // The decays lead by different amounts at epoch 20: the race compared something.
    EXPECT_NE(atRace[0], atRace[2]);
}

// The race within each weight decay (--race-epochs without --race-all): a decay's starts race at epoch 20 as all
// candidates of that decay alone would (raceAll with the one decay), and the decays' survivors are compared at their
// ends: the two-decay race keeps the lower final held-out error of the two one-decay races, bit for bit.
TEST(Trainer, RaceWithinEachDecayComparesTheDecaysAtTheirEnds) {
    const VoxelGrid grid = unitVoxel();
    const std::vector<TrainingSample> samples = makeSamples(grid, smooth, 600);
    const std::vector<const TrainingSample*> ptrs = pointersTo(samples);
    TrainSettings settings;
    settings.epochs = 80;
    settings.patience = 80;
    settings.weightDecays = {0.0f, 400.0f};
    settings.restarts = 3;
    settings.raceEpochs = 20;
    std::vector<VoxelTrainResult> perDecay;
    bool raceMattered = false;
    for (float decay : settings.weightDecays) {
        TrainSettings one = settings;
        one.weightDecays = {decay};
        perDecay.push_back(trainVoxel(grid, 0, ptrs, one));
        one.raceAll = true;  // one decay: the same race
        EXPECT_EQ(trainVoxel(grid, 0, ptrs, one).params, perDecay.back().params);
        one.raceEpochs = 0;
        raceMattered = raceMattered || trainVoxel(grid, 0, ptrs, one).params != perDecay.back().params;
    }
    const VoxelTrainResult both = trainVoxel(grid, 0, ptrs, settings);
    const size_t better = perDecay[1].heldOutRelMse < perDecay[0].heldOutRelMse ? 1 : 0;
    EXPECT_EQ(both.params, perDecay[better].params);
    EXPECT_EQ(both.weightDecay, settings.weightDecays[better]);
    EXPECT_EQ(both.heldOutRelMse, perDecay[better].heldOutRelMse);
    EXPECT_TRUE(raceMattered) << "the start ahead at epoch 20 ended best in both decays: the race chose nothing here";
}

// Grey where grey (TrainSettings::greyWhereGrey): trained on grey targets, a network's three outputs are equal
// bit for bit (no false tint in a grey scene), and no worse than the channels trained apart; on coloured
// targets nothing changes.
TEST(Trainer, GreyTargetsGiveAGreyNetworkNoWorseThanItsChannels) {
    const VoxelGrid grid = unitVoxel();
    std::vector<TrainingSample> grey = makeSamples(grid, smooth, 800);
    for (TrainingSample& t : grey) t.radiance = glm::vec3(t.radiance.y);
    TrainSettings settings;
    settings.epochs = 80;
    settings.weightDecays = {0.0f};
    const VoxelTrainResult r = trainVoxel(grid, 0, pointersTo(grey), settings);
    const size_t n = r.params.size(), hidden = size_t(settings.shape.hidden.back());
    const float* W = &r.params[n - 3 - 3 * hidden];  // the output layer's rows, then its biases
    for (size_t j = 0; j < hidden; ++j) {
        EXPECT_EQ(W[j], W[hidden + j]) << j;
        EXPECT_EQ(W[j], W[2 * hidden + j]) << j;
    }
    EXPECT_EQ(r.params[n - 3], r.params[n - 2]);
    EXPECT_EQ(r.params[n - 3], r.params[n - 1]);
    // Without it the same training tints (the rows differ), and its error is no lower.
    TrainSettings apart = settings;
    apart.greyWhereGrey = false;
    const VoxelTrainResult u = trainVoxel(grid, 0, pointersTo(grey), apart);
    EXPECT_NE(u.params[n - 3 - 3 * hidden], u.params[n - 3 - 2 * hidden]);
    EXPECT_LE(r.heldOutRelMse, u.heldOutRelMse);
    // Coloured targets: the same network either way, bit for bit.
    const std::vector<TrainingSample> colour = makeSamples(grid, smooth, 800);
    EXPECT_EQ(trainVoxel(grid, 0, pointersTo(colour), settings).params, trainVoxel(grid, 0, pointersTo(colour), apart).params);
}

TEST(Trainer, SingleSampleVoxelAndConstantTargets) {
    Bounds3 bounds;
    bounds.extend(glm::vec3(0.0f));
    bounds.extend(glm::vec3(1.0f));
    VoxelGrid grid(bounds, glm::uvec3(1));
    TrainingSample s{glm::vec3(0.5f), glm::vec3(0, 0, 1), glm::vec3(0, 0, 1), glm::vec3(2.0f, 1.0f, 0.5f), 0};
    const TrainSettings settings;
    VoxelTrainResult r = trainVoxel(grid, 0, {&s}, settings);
    EXPECT_EQ(r.trainCount, 1u);
    EXPECT_EQ(r.heldOutCount, 0u);
    EXPECT_LT(r.heldOutRelMse, 1e-3);  // judged on its one sample
    for (float p : r.params) ASSERT_TRUE(std::isfinite(p));
    // Black voxel: all targets zero, scale stays finite and positive.
    TrainingSample black = s;
    black.radiance = glm::vec3(0.0f);
    VoxelTrainResult rb = trainVoxel(grid, 0, {&black, &black, &black}, settings);
    EXPECT_GT(rb.scale, 0.0f);
    EXPECT_TRUE(std::isfinite(rb.scale));
    // Nothing to learn: the zero network, exactly (a trained one left noise of 5e-4 around zero), untrained.
    EXPECT_EQ(rb.heldOutRelMse, 0.0);
    EXPECT_EQ(rb.params, std::vector<float>(rb.params.size(), 0.0f));
    EXPECT_EQ(rb.epochs, 0);
    EXPECT_EQ(rb.attempts, 0);
    EXPECT_TRUE(rb.events.empty());
    EXPECT_FALSE(rb.fallback);
}

}  // namespace
}  // namespace nrad

namespace nrad {
namespace {

TEST(Trainer, DivergentTrainingIsDetectedRetriedAndNeverStoresNonFiniteWeights) {
    const VoxelGrid grid = unitVoxel();
    const std::vector<TrainingSample> samples = makeSamples(grid, smooth, 400);
    const std::vector<const TrainingSample*> ptrs = pointersTo(samples);
    TrainSettings settings;
    settings.learningRate = 1e30f;  // every attempt blows up
    settings.epochs = 20;
    VoxelTrainResult r = trainVoxel(grid, 0, ptrs, settings);
    EXPECT_EQ(r.attempts, settings.maxAttempts);
    EXPECT_TRUE(r.fallback);
    ASSERT_EQ(r.events.size(), size_t(settings.maxAttempts) + 1);
    EXPECT_NE(r.events[0].find("re-initialised"), std::string::npos) << r.events[0];
    EXPECT_NE(r.events.back().find("fallback"), std::string::npos);
    for (float p : r.params) ASSERT_TRUE(std::isfinite(p));
    EXPECT_TRUE(std::isfinite(r.heldOutRelMse));
    // The fallback predicts the voxel's mean radiance: a finite, moderate error on this smooth target.
    EXPECT_LT(r.heldOutRelMse, 0.5);
}

}  // namespace
}  // namespace nrad
