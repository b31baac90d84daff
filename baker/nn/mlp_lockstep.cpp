// Networks in lockstep: their interleaved storage, the plain lanes (std::fma: a libm call where the CPU has no
// fused multiply-add, the same bits), and the choice of kernels at run time.
#include <cstdlib>
#include <cstring>

#define NRAD_LOCKSTEP_KERNELS lockstep_plain
#include "baker/nn/mlp_lockstep_impl.h"

#include "baker/nn/mlp_batch.h"  // cpuHasAvx2

namespace nrad {
namespace lockstep_plain {
namespace {

// W lanes as plain floats, lane by lane.
template <int N>
struct Lanes {
    static constexpr int W = N;
    static constexpr int kGradInputs = 4;
    float f[N];
    static Lanes splat(float x) { return each([&](int) { return x; }); }
    static Lanes load(const float* p) { return each([&](int j) { return p[j]; }); }
    static void store(float* p, Lanes a) {
        for (int j = 0; j < N; ++j) p[j] = a.f[j];
    }
    static void transposeRows(const float* const rows[N], float* out) {
        for (int q = 0; q < kPackedFloats; ++q)
            for (int j = 0; j < N; ++j) out[size_t(q) * N + size_t(j)] = rows[j][q];
    }
    // The lanes of f(j), j = 0 .. N - 1.
    template <class F>
    static Lanes each(F f) {
        Lanes r;
        for (int j = 0; j < N; ++j) r.f[j] = f(j);
        return r;
    }
    friend Lanes operator+(Lanes a, Lanes b) { return each([&](int j) { return a.f[j] + b.f[j]; }); }
    friend Lanes operator-(Lanes a, Lanes b) { return each([&](int j) { return a.f[j] - b.f[j]; }); }
    friend Lanes operator*(Lanes a, Lanes b) { return each([&](int j) { return a.f[j] * b.f[j]; }); }
    friend Lanes operator/(Lanes a, Lanes b) { return each([&](int j) { return a.f[j] / b.f[j]; }); }
    friend Lanes sqrt(Lanes a) { return each([&](int j) { return std::sqrt(a.f[j]); }); }
    friend Lanes fma(Lanes a, Lanes b, Lanes c) { return each([&](int j) { return std::fma(a.f[j], b.f[j], c.f[j]); }); }
    friend Lanes whereAboveZero(Lanes p, Lanes v) { return each([&](int j) { return p.f[j] > 0.0f ? v.f[j] : 0.0f; }); }
    friend Lanes whereLess(Lanes a, Lanes b, Lanes v) { return each([&](int j) { return a.f[j] < b.f[j] ? v.f[j] : 0.0f; }); }
    friend Lanes selectAboveZero(Lanes m, Lanes a, Lanes b) { return each([&](int j) { return m.f[j] > 0.0f ? a.f[j] : b.f[j]; }); }
};

}  // namespace

void trainStep(LockstepNetworks& nets, const LockstepLane* lanes, LossKind loss, LockstepWorkspace& ws) {
    if (nets.lanes == 16)
        stepWith<Lanes<16>>(nets, lanes, loss, ws);
    else
        stepWith<Lanes<8>>(nets, lanes, loss, ws);
}

}  // namespace lockstep_plain

LockstepNetworks::LockstepNetworks(const NetworkShape& s, int laneCount) : shape(s), lanes(laneCount) {
    size_t at = 0;
    int in = shape.inputs;
    const size_t layers = shape.hidden.size() + 1;
    for (size_t l = 0; l < layers; ++l) {
        const int out = l + 1 == layers ? shape.outputs : shape.hidden[l];
        offsets.push_back(at);
        at += size_t(out) * size_t(in) + size_t(out);
        in = out;
    }
    params.assign(at * size_t(lanes), 0.0f);
    m.assign(params.size(), 0.0f);
    v.assign(params.size(), 0.0f);
}

void LockstepNetworks::setLane(int lane, const std::vector<float>& p) {
    for (size_t q = 0; q < p.size(); ++q) {
        const size_t at = q * size_t(lanes) + size_t(lane);
        params[at] = p[q];
        m[at] = 0.0f;
        v[at] = 0.0f;
    }
}

void LockstepNetworks::getLane(int lane, std::vector<float>& p) const {
    p.resize(parameterCount());
    for (size_t q = 0; q < p.size(); ++q) p[q] = params[q * size_t(lanes) + size_t(lane)];
}

void LockstepNetworks::getLaneState(int lane, std::vector<float>& p, std::vector<float>& mOut, std::vector<float>& vOut) const {
    getLane(lane, p);
    mOut.resize(p.size());
    vOut.resize(p.size());
    for (size_t q = 0; q < p.size(); ++q) {
        mOut[q] = m[q * size_t(lanes) + size_t(lane)];
        vOut[q] = v[q * size_t(lanes) + size_t(lane)];
    }
}

void LockstepNetworks::setLaneState(int lane, const std::vector<float>& p, const std::vector<float>& mIn, const std::vector<float>& vIn) {
    for (size_t q = 0; q < p.size(); ++q) {
        const size_t at = q * size_t(lanes) + size_t(lane);
        params[at] = p[q];
        m[at] = mIn[q];
        v[at] = vIn[q];
    }
}

const std::vector<LockstepKernel>& lockstepKernels() {
    static const std::vector<LockstepKernel> kernels = [] {
        std::vector<LockstepKernel> out = {{"plain", 8, lockstep_plain::trainStep}, {"plain16", 16, lockstep_plain::trainStep}};
#if defined(__x86_64__) && !defined(NRAD_LOCKSTEP_PLAIN_ONLY)
        __builtin_cpu_init();
        if (cpuHasAvx2() && __builtin_cpu_supports("fma")) out.push_back({"avx2", 8, lockstep_avx2::trainStep});
        if (__builtin_cpu_supports("avx512f")) out.push_back({"avx512", 16, lockstep_avx512::trainStep});
#endif
#if defined(__aarch64__) && !defined(NRAD_LOCKSTEP_PLAIN_ONLY)
        out.push_back({"neon", 8, lockstep_neon::trainStep});
#endif
        return out;
    }();
    return kernels;
}

const LockstepKernel& lockstepKernel(int maxLanes) {
    const std::vector<LockstepKernel>& all = lockstepKernels();
    static const char* const forced = std::getenv("NRAD_TRAIN_KERNEL");
    if (forced && *forced)
        for (const LockstepKernel& k : all)
            if (!std::strcmp(k.name, forced) && k.lanes <= maxLanes) return k;
    for (size_t k = all.size(); k-- > 0;)  // the instruction sets' kernels last, the widest last of all
        if (all[k].lanes <= maxLanes && std::strcmp(all[k].name, "plain16") != 0) return all[k];
    return all.front();
}

}  // namespace nrad
