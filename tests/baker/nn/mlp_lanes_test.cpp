// The mini-batch kernels' exact bits (Mlp::forwardBatch / backwardBatch): a hash of every output and gradient
// of fixed networks and batches, the same constant for the lanes bake_unit_tests runs (AVX2 where the CPU has
// it), the SSE2 lanes of machines without (mlp_sse2_lanes_tests) and the plain-array lanes of non-x86 machines
// (mlp_plain_lanes_tests: baker/nn/mlp.cpp compiled without __SSE2__), and the value the kernels gave before
// they were written over explicit lanes. A changed sum order, a fused multiply-add or a
// lane mixed up changes it.
#include <cstdint>
#include <cstring>
#include <vector>

#include <gtest/gtest.h>

#include "baker/nn/mlp.h"
#include "baker/nn/random.h"

namespace nrad {
namespace {

uint64_t fnv1a(uint64_t h, float v) {
    uint32_t bits;
    std::memcpy(&bits, &v, sizeof bits);
    for (int b = 0; b < 4; ++b) {
        h ^= (bits >> (8 * b)) & 0xffu;
        h *= 0x100000001b3ull;
    }
    return h;
}

TEST(MlpLanes, BatchKernelsGiveTheirGoldenBits) {
    uint64_t h = 0xcbf29ce484222325ull;
    for (std::vector<int> hidden : {std::vector<int>{9}, std::vector<int>{16, 7}}) {
        NetworkShape shape;
        shape.hidden = hidden;
        Mlp mlp(shape);
        mlp.initialize(11, 0.2f);
        SplitMix64 rng(17);
        MlpBatchWorkspace ws;
        for (int count : {1, 5, 8, 13, 32, 64}) {
            std::vector<float> x(size_t(count) * 9), grad(mlp.parameters().size(), 0.0f);
            for (float& v : x) v = 2.0f * rng.uniform() - 1.0f;
            mlp.forwardBatch(x.data(), count, ws);
            const size_t last = mlp.layers();
            for (int c = 0; c < 3; ++c)
                for (int k = 0; k < count; ++k) {
                    h = fnv1a(h, ws.value(last, c)[k]);
                    ws.delta(last, c)[k] = ws.value(last, c)[k] - (2.0f * rng.uniform() - 1.0f);
                }
            mlp.backwardBatch(ws, grad.data());
            for (float g : grad) h = fnv1a(h, g);
        }
    }
    EXPECT_EQ(h, 8215576952579362950ull);
}

}  // namespace
}  // namespace nrad
