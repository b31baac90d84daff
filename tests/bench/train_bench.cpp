// Training throughput of the voxel networks against the machine's FMA peak, measured in the same run (issue 40).
//
// Per network shape: one training step on a mini-batch of 32 (Mlp::forwardBatch, the loss's gradient,
// Mlp::backwardBatch, Adam::step), timed part by part (the best of --repeat runs), and sample-epochs per second
// on 1 and 2 threads (each thread its own network, as the baker trains voxels in parallel). Throughput is
// counted in multiply-adds: forward sum(in x out) and backward 2 sum(in x out) less the inputs' deltas
// (in x out of the first layer) per sample; Adam's per-parameter work is timed, not counted. Its fraction of
// the peak (lane-FMAs per second of fma_peak.h at the widest vector width) is what issue 40's goal 1 asks
// about: >= 30% on one core.
//
// Usage: train_bench [--steps 200000] [--repeat 3] [--threads 2] [--kernel plain|plain16|avx2|avx512|neon]
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <string>
#include <thread>
#include <vector>

#include "baker/nn/adam.h"
#include "baker/nn/mlp.h"
#include "baker/nn/mlp_lockstep.h"
#include "fma_peak.h"

using namespace nrad;

namespace {

using Clock = std::chrono::steady_clock;
constexpr int kBatch = 32;

// Multiply-adds of one sample's forward and backward pass.
double macsPerSample(const NetworkShape& s) {
    double forward = 0.0, first = 0.0;
    int in = s.inputs;
    for (size_t l = 0; l <= s.hidden.size(); ++l) {
        const int out = l < s.hidden.size() ? s.hidden[l] : s.outputs;
        forward += double(in) * double(out);
        if (l == 0) first = double(in) * double(out);
        in = out;
    }
    return forward + 2.0 * forward - first;
}

std::string shapeName(const NetworkShape& s) {
    std::string n = std::to_string(s.inputs);
    for (int h : s.hidden) n += "-" + std::to_string(h);
    return n + "-" + std::to_string(s.outputs);
}

struct Trainer {
    Mlp mlp;
    Adam adam;
    MlpBatchWorkspace ws;
    std::vector<float> x, grad;

    explicit Trainer(const NetworkShape& shape, uint64_t seed)
        : mlp(shape), adam(mlp.parameters().size()), x(size_t(kBatch) * size_t(shape.inputs)), grad(mlp.parameters().size()) {
        mlp.initialize(seed, 1.0f);
        for (size_t i = 0; i < x.size(); ++i) x[i] = float((i * 37 + seed) % 101) / 101.0f - 0.3f;
    }
    // One step; t (if given) accumulates the forward, backward and Adam seconds.
    void step(double* t) {
        const auto t0 = Clock::now();
        mlp.forwardBatch(x.data(), kBatch, ws);
        const auto t1 = Clock::now();
        const size_t last = mlp.layers();
        for (int c = 0; c < mlp.shape().outputs; ++c)
            for (int k = 0; k < kBatch; ++k) ws.delta(last, c)[k] = (ws.value(last, c)[k] - 0.5f) * (1.0f / float(kBatch));
        std::fill(grad.begin(), grad.end(), 0.0f);
        mlp.backwardBatch(ws, grad.data());
        const auto t2 = Clock::now();
        adam.step(mlp.parameters(), grad, 1e-4f);
        if (t) {
            const auto t3 = Clock::now();
            t[0] += std::chrono::duration<double>(t1 - t0).count();
            t[1] += std::chrono::duration<double>(t2 - t1).count();
            t[2] += std::chrono::duration<double>(t3 - t2).count();
        }
    }
};

// A kernel's lanes of networks in lockstep (mlp_lockstep.h), each lane a mini-batch of kBatch of its own 512
// samples.
struct LockstepTrainer {
    LockstepKernel kernel;
    LockstepNetworks nets;
    LockstepWorkspace ws;
    std::vector<float> samples;
    LockstepLane lanes[kMaxLockstepLanes];
    int t = 0;

    LockstepTrainer(const LockstepKernel& k, const NetworkShape& shape, uint64_t seed)
        : kernel(k), nets(shape, k.lanes), samples(size_t(512) * size_t(k.lanes) * kPackedFloats) {
        for (size_t i = 0; i < samples.size(); ++i) samples[i] = float((i * 37 + seed) % 101) / 101.0f - 0.3f;
        for (int j = 0; j < kernel.lanes; ++j) {
            Mlp mlp(shape);
            mlp.initialize(seed * 16 + uint64_t(j), 1.0f);
            nets.setLane(j, mlp.parameters());
            lanes[j].count = kBatch;
            lanes[j].learningRate = 1e-4f;
        }
    }
    void step() {
        ++t;
        for (int j = 0; j < kernel.lanes; ++j) {
            for (int k = 0; k < kBatch; ++k)
                lanes[j].rows[k] = &samples[((size_t(j) * 512) + size_t((t * kBatch + k) % 512)) * kPackedFloats];
            lanes[j].c1 = float(1.0 - std::pow(0.9, t));
            lanes[j].c2 = float(1.0 - std::pow(0.999, t));
        }
        kernel.step(nets, lanes, LossKind::RelativeL2, ws);
    }
};

// Sample-epochs per second of `threads` threads, each training its own network (with a lockstep kernel: its own
// kernel->lanes networks) for `steps` steps.
double sampleRate(const NetworkShape& shape, int threads, int steps, const LockstepKernel* lockstep) {
    std::vector<std::thread> pool;
    const auto t0 = Clock::now();
    const int perStep = lockstep ? lockstep->lanes : 1;
    for (int t = 0; t < threads; ++t)
        pool.emplace_back([&shape, steps, t, lockstep, perStep] {
            if (lockstep) {
                LockstepTrainer tr(*lockstep, shape, uint64_t(t) + 1);
                for (int s = 0; s < steps / perStep; ++s) tr.step();
            } else {
                Trainer tr(shape, uint64_t(t) + 1);
                for (int s = 0; s < steps; ++s) tr.step(nullptr);
            }
        });
    for (std::thread& t : pool) t.join();
    return double(threads) * double(steps / perStep * perStep) * kBatch / std::chrono::duration<double>(Clock::now() - t0).count();
}

}  // namespace

int main(int argc, char** argv) {
    int steps = 200000, repeat = 3, threads = 2;
    std::string only;  // --kernel NAME: that lockstep kernel alone
    for (int i = 1; i + 1 < argc; i += 2) {
        if (!std::strcmp(argv[i], "--steps")) steps = std::max(1, std::atoi(argv[i + 1]));
        else if (!std::strcmp(argv[i], "--kernel")) only = argv[i + 1];
        else if (!std::strcmp(argv[i], "--repeat")) repeat = std::max(1, std::atoi(argv[i + 1]));
        else if (!std::strcmp(argv[i], "--threads")) threads = std::max(1, std::atoi(argv[i + 1]));
    }
#if defined(__x86_64__)
    const int width = fma_peak::widestFmaWidth();
    const double peak1 = width ? fma_peak::fmaPeak(1, width) : 0.0, peakN = width ? fma_peak::fmaPeak(threads, width) : 0.0;
#else
    const int width = 0;
    const double peak1 = 0.0, peakN = 0.0;
#endif
    std::printf("FMA peak (%d-wide): %.1f G lane-FMA/s on 1 thread, %.1f G on %d\n", width, peak1 * 1e-9, peakN * 1e-9, threads);
    std::printf("| shape | forward / backward / Adam, ns per step of %d | sample-epochs/s, 1 thread | of the 1-thread peak | "
                "%d threads | speed-up | of the %d-thread peak |\n|---|---|---|---|---|---|---|\n",
                kBatch, threads, threads);
    for (const std::vector<int>& hidden : std::vector<std::vector<int>>{{9}, {16}, {32}, {16, 16}}) {
        NetworkShape shape;
        shape.hidden = hidden;
        double best[3] = {1e30, 1e30, 1e30}, rate1 = 0.0, rateN = 0.0;
        for (int r = 0; r < repeat; ++r) {
            Trainer tr(shape, 1);
            double t[3] = {0, 0, 0};
            for (int s = 0; s < steps / 4; ++s) tr.step(t);
            for (int k = 0; k < 3; ++k) best[k] = std::min(best[k], t[k] / double(steps / 4) * 1e9);
            rate1 = std::max(rate1, sampleRate(shape, 1, steps, nullptr));
            rateN = std::max(rateN, sampleRate(shape, threads, steps, nullptr));
        }
        const double macs = macsPerSample(shape);
        std::printf("| %s | %.0f / %.0f / %.0f | %.3g M | %.1f%% | %.3g M | %.2fx | %.1f%% |\n", shapeName(shape).c_str(), best[0], best[1],
                    best[2], rate1 * 1e-6, peak1 > 0 ? 100.0 * rate1 * macs / peak1 : 0.0, rateN * 1e-6, rateN / rate1,
                    peakN > 0 ? 100.0 * rateN * macs / peakN : 0.0);
    }
    std::printf("\nLockstep, one network per lane (mlp_lockstep.h; the baker trains with %s):\n| kernel | shape | ns per step of "
                "lanes x %d | sample-epochs/s, 1 thread | of the 1-thread peak | %d threads | speed-up | of the %d-thread peak |\n"
                "|---|---|---|---|---|---|---|---|\n",
                lockstepKernel().name, kBatch, threads, threads);
    for (const LockstepKernel& kernel : lockstepKernels()) {
        if (!only.empty() && only != kernel.name) continue;
        for (const std::vector<int>& hidden : std::vector<std::vector<int>>{{9}, {16}, {32}, {16, 16}}) {
            NetworkShape shape;
            shape.hidden = hidden;
            double rate1 = 0.0, rateN = 0.0;
            const int kernelSteps = std::strncmp(kernel.name, "plain", 5) ? steps : std::max(kernel.lanes, steps / 8);  // plain lanes are slow
            for (int r = 0; r < repeat; ++r) {
                rate1 = std::max(rate1, sampleRate(shape, 1, kernelSteps, &kernel));
                rateN = std::max(rateN, sampleRate(shape, threads, kernelSteps, &kernel));
            }
            const double macs = macsPerSample(shape);
            std::printf("| %s | %s | %.0f | %.3g M | %.1f%% | %.3g M | %.2fx | %.1f%% |\n", kernel.name, shapeName(shape).c_str(),
                        1e9 * kernel.lanes * kBatch / rate1, rate1 * 1e-6, peak1 > 0 ? 100.0 * rate1 * macs / peak1 : 0.0, rateN * 1e-6,
                        rateN / rate1, peakN > 0 ? 100.0 * rateN * macs / peakN : 0.0);
        }
    }
    return 0;
}
