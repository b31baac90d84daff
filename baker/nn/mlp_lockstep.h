// Networks of one shape trained in lockstep, one network per lane of a SIMD register (issue 40): every
// operation is vertical (lane j only ever meets lane j), so there are no horizontal sums, no broadcasts and no
// shuffles in the arithmetic, and each lane computes exactly what a plain loop over its own network computes:
// every multiply-add fused (std::fma in the plain lanes), every sum in the order written below. The result of a
// lane is therefore independent of the other lanes, of the lane it runs in and of the instruction set
// (tests/baker/nn/mlp_lockstep_test.cpp holds each to a plain scalar reference, bit for bit).
//
// One step (LockstepKernel::step) is a whole mini-batch step of each lane's network: forward, the regression loss's
// gradient, backpropagation, the gradient summed over the batch, divided by its count, the L2 penalty, and Adam.
//
// The number of lanes is the kernel's: 8 for AVX2, NEON and the plain lanes, 16 for AVX-512 (and the plain lanes'
// 16, for tests). Since a lane's result does
// not depend on its neighbours, it does not depend on how many there are either: every kernel gives the same
// networks, and so the same assets.
#pragma once

#include <cmath>
#include <cstddef>
#include <vector>

#include "baker/nn/loss.h"
#include "baker/nn/mlp.h"

namespace nrad {

constexpr int kMaxLockstepLanes = 16;
// A training sample packed for the lanes: inputs (9), loss targets in the output space (3, lossTarget), per-channel
// loss weights (3), one float of padding.
constexpr int kPackedInputs = 9, kPackedTarget = 9, kPackedWeight = 12, kPackedFloats = 16;

// Parameters and Adam's moments of `lanes` networks, interleaved: parameter q of lane j at [q lanes + j] (q in the
// Mlp layout).
struct LockstepNetworks {
    LockstepNetworks(const NetworkShape& shape, int lanes);
    NetworkShape shape;
    int lanes;
    std::vector<size_t> offsets;  // of each layer's parameters (W out x in, then b), as Mlp's
    std::vector<float> params, m, v;
    size_t parameterCount() const { return offsets.empty() ? 0 : params.size() / size_t(lanes); }
    // Lane j's parameters in or out, in the Mlp layout; setLane also zeroes its Adam moments.
    void setLane(int lane, const std::vector<float>& p);
    void getLane(int lane, std::vector<float>& p) const;
    // Lane j's parameters and Adam moments out and back in (a training paused in one lane and resumed in another).
    void getLaneState(int lane, std::vector<float>& p, std::vector<float>& mOut, std::vector<float>& vOut) const;
    void setLaneState(int lane, const std::vector<float>& p, const std::vector<float>& mIn, const std::vector<float>& vIn);
};

// One step's inputs per lane: count samples (0: the lane rests, nothing of it changes), rows[k] the packed sample
// k (kPackedFloats floats), the learning rate, the L2 penalty per parameter (added to the mean gradient as
// weightDecay x parameter on every parameter but the output biases, where > 0), and Adam's bias corrections
// c1 = 1 - beta1^t, c2 = 1 - beta2^t of this step.
struct LockstepLane {
    int count = 0;
    const float* rows[MlpBatchWorkspace::kMaxBatch] = {};
    float learningRate = 0.0f, weightDecay = 0.0f, c1 = 1.0f, c2 = 1.0f;
};

// Scratch space of a step, sized on first use.
struct LockstepWorkspace {
    int lanes = 0;
    std::vector<float> buffer;
    float *values = nullptr, *deltas = nullptr, *grad = nullptr;  // in buffer
    std::vector<size_t> at;  // each layer's activations (layer 0: the packed rows)
};

// Adam's constants, the same as Adam's (adam.h), and a step's rate and epsilon with the bias corrections folded in
// (Kingma and Ba, Sec. 2): p -= rate m / (sqrt(v) + epsilon), rate = learningRate sqrt(c2) / c1,
// epsilon = 1e-8 sqrt(c2).
constexpr float kAdamBeta1 = 0.9f, kAdamBeta2 = 0.999f, kAdamEpsilon = 1e-8f;
struct AdamRates {
    float rate, epsilon;
};
inline AdamRates adamRates(float learningRate, float c1, float c2) {
    const double root = std::sqrt(double(c2));
    return {float(double(learningRate) * root / double(c1)), float(double(kAdamEpsilon) * root)};
}

// A kernel: its name, its lanes and its step: one mini-batch step of every lane (nets.lanes of them, which must be
// `lanes`) with count > 0. The loss: LossKind's regression gradient (lossTarget already applied to the packed
// targets), each channel weighing its packed weight. Inputs, shape: 9 in, 3 out.
using LockstepStep = void (*)(LockstepNetworks& nets, const LockstepLane* lanes, LossKind loss, LockstepWorkspace& ws);
struct LockstepKernel {
    const char* name;
    int lanes;
    LockstepStep step;
};
// The kernels this CPU can run, plain first: "plain" (8 lanes, std::fma), "plain16" (the same with 16 lanes),
// "avx2" (AVX2 with FMA, 8 lanes), "avx512" (AVX-512F, 16 lanes), "neon" (AArch64, 8 lanes).
const std::vector<LockstepKernel>& lockstepKernels();
// The kernel to train with, of at most maxLanes lanes: the one the environment's NRAD_TRAIN_KERNEL names where this
// CPU runs it and it fits, else the fastest that fits (avx512, avx2 or neon, plain).
const LockstepKernel& lockstepKernel(int maxLanes = kMaxLockstepLanes);

// The kernels of one instruction set.
namespace lockstep_plain {  // 8 or 16 lanes, as nets.lanes
void trainStep(LockstepNetworks& nets, const LockstepLane* lanes, LossKind loss, LockstepWorkspace& ws);
}
#if defined(__x86_64__)
namespace lockstep_avx2 {  // AVX2 with FMA, 8 lanes
void trainStep(LockstepNetworks& nets, const LockstepLane* lanes, LossKind loss, LockstepWorkspace& ws);
}
namespace lockstep_avx512 {  // AVX-512F, 16 lanes
void trainStep(LockstepNetworks& nets, const LockstepLane* lanes, LossKind loss, LockstepWorkspace& ws);
}
#endif
#if defined(__aarch64__)
namespace lockstep_neon {  // NEON, 8 lanes
void trainStep(LockstepNetworks& nets, const LockstepLane* lanes, LossKind loss, LockstepWorkspace& ws);
}
#endif

}  // namespace nrad
