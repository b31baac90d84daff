// Networks in lockstep: their interleaved storage, the plain lanes (std::fma: a libm call where the CPU has no
// fused multiply-add, the same bits), and the choice of kernels at run time.
#define NRAD_LOCKSTEP_KERNELS lockstep_plain
#include "baker/nn/mlp_lockstep_impl.h"

#include "baker/nn/mlp_batch.h"  // cpuHasAvx2

namespace nrad {

LockstepNetworks::LockstepNetworks(const NetworkShape& s) : shape(s) {
    size_t at = 0;
    int in = shape.inputs;
    const size_t layers = shape.hidden.size() + 1;
    for (size_t l = 0; l < layers; ++l) {
        const int out = l + 1 == layers ? shape.outputs : shape.hidden[l];
        offsets.push_back(at);
        at += size_t(out) * size_t(in) + size_t(out);
        in = out;
    }
    params.assign(at * kLockstepLanes, 0.0f);
    m.assign(params.size(), 0.0f);
    v.assign(params.size(), 0.0f);
}

void LockstepNetworks::setLane(int lane, const std::vector<float>& p) {
    for (size_t q = 0; q < p.size(); ++q) {
        const size_t at = q * kLockstepLanes + size_t(lane);
        params[at] = p[q];
        m[at] = 0.0f;
        v[at] = 0.0f;
    }
}

void LockstepNetworks::getLane(int lane, std::vector<float>& p) const {
    p.resize(parameterCount());
    for (size_t q = 0; q < p.size(); ++q) p[q] = params[q * kLockstepLanes + size_t(lane)];
}

void LockstepNetworks::getLaneState(int lane, std::vector<float>& p, std::vector<float>& mOut, std::vector<float>& vOut) const {
    getLane(lane, p);
    mOut.resize(p.size());
    vOut.resize(p.size());
    for (size_t q = 0; q < p.size(); ++q) {
        mOut[q] = m[q * kLockstepLanes + size_t(lane)];
        vOut[q] = v[q * kLockstepLanes + size_t(lane)];
    }
}

void LockstepNetworks::setLaneState(int lane, const std::vector<float>& p, const std::vector<float>& mIn, const std::vector<float>& vIn) {
    for (size_t q = 0; q < p.size(); ++q) {
        const size_t at = q * kLockstepLanes + size_t(lane);
        params[at] = p[q];
        m[at] = mIn[q];
        v[at] = vIn[q];
    }
}

namespace {
#if defined(__x86_64__)
bool cpuHasAvx2Fma() {
    static const bool yes = [] {
        __builtin_cpu_init();
        return cpuHasAvx2() && __builtin_cpu_supports("fma") != 0;
    }();
    return yes;
}
#endif
}  // namespace

void lockstepTrainStep(LockstepNetworks& nets, const LockstepLane lanes[kLockstepLanes], LossKind loss, LockstepWorkspace& ws) {
#if defined(__x86_64__) && !defined(NRAD_LOCKSTEP_PLAIN_ONLY)
    if (cpuHasAvx2Fma()) return lockstep_avx2::trainStep(nets, lanes, loss, ws);
#endif
    lockstep_plain::trainStep(nets, lanes, loss, ws);
}

}  // namespace nrad
