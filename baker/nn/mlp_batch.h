// Mlp's mini-batch kernels, one set per instruction set (mlp_batch_impl.h compiled by mlp_batch_sse2.cpp and,
// on x86-64, mlp_batch_avx2.cpp), and the CPU test that picks one (Mlp::forwardBatch).
#pragma once

#include <cstddef>
#include <vector>

#include "baker/nn/mlp.h"

namespace nrad {

struct MlpBatchKernels {
    void (*forward)(const NetworkShape& shape, const std::vector<float>& params, const std::vector<size_t>& offsets,
                    const float* x, int count, MlpBatchWorkspace& ws);
    void (*backward)(const NetworkShape& shape, const std::vector<float>& params, const std::vector<size_t>& offsets,
                     MlpBatchWorkspace& ws, float* grad);
};
extern const MlpBatchKernels kMlpBatchBaseline;  // SSE2 on x86-64, plain arrays elsewhere
#if defined(__x86_64__)
extern const MlpBatchKernels kMlpBatchAvx2;

// Whether the CPU runs AVX2, asked once.
inline bool cpuHasAvx2() {
    static const bool avx2 = [] {
        __builtin_cpu_init();
        return __builtin_cpu_supports("avx2") != 0;
    }();
    return avx2;
}
#endif

}  // namespace nrad
