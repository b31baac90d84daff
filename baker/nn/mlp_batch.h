// Mlp's mini-batch kernels, one set per instruction set (mlp_batch_impl.h compiled by mlp_batch_sse2.cpp and,
// on x86-64, mlp_batch_avx2.cpp), and the CPU test that picks one (Mlp::forwardBatch).
#pragma once

#include <cstddef>
#include <vector>

#include "baker/nn/mlp.h"

namespace nrad {

// The kernels of one instruction set: Mlp::forwardBatch on a prepared workspace, and Mlp::backwardBatch. Called
// directly, not through a table of function pointers: the table measured up to 25% slower on the larger shapes
// (train_bench).
namespace mlp_sse2 {  // the baseline: SSE2 on x86-64, plain arrays elsewhere
void forwardBatch(const NetworkShape& shape, const std::vector<float>& params, const std::vector<size_t>& offsets, const float* x,
                  int count, MlpBatchWorkspace& ws);
void backwardBatch(const NetworkShape& shape, const std::vector<float>& params, const std::vector<size_t>& offsets,
                   MlpBatchWorkspace& ws, float* grad);
}  // namespace mlp_sse2
#if defined(__x86_64__)
namespace mlp_avx2 {
void forwardBatch(const NetworkShape& shape, const std::vector<float>& params, const std::vector<size_t>& offsets, const float* x,
                  int count, MlpBatchWorkspace& ws);
void backwardBatch(const NetworkShape& shape, const std::vector<float>& params, const std::vector<size_t>& offsets,
                   MlpBatchWorkspace& ws, float* grad);
}  // namespace mlp_avx2

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
