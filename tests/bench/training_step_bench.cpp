// One training step of a 9-9-3 voxel network on a mini-batch of 32 (Mlp::forwardBatch, Mlp::backwardBatch,
// Adam::step), timed part by part over many steps: nanoseconds per step, the best of --repeat runs (the
// steady_clock reads between the parts are included; docs/performance.md, "Batch kernels in explicit vectors").
// Usage: training_step_bench [--steps 1000000] [--repeat 3]
#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <vector>

#include "baker/nn/adam.h"
#include "baker/nn/mlp.h"

using namespace nrad;

int main(int argc, char** argv) {
    int steps = 1000000, repeat = 3;
    for (int i = 1; i + 1 < argc; i += 2) {
        if (!std::strcmp(argv[i], "--steps")) steps = std::max(1, std::atoi(argv[i + 1]));
        else if (!std::strcmp(argv[i], "--repeat")) repeat = std::max(1, std::atoi(argv[i + 1]));
    }
    NetworkShape shape;  // 9-9-3, the asset's network
    Mlp mlp(shape);
    mlp.initialize(1, 1.0f);
    Adam adam(mlp.parameters().size());
    MlpBatchWorkspace ws;
    const int batch = 32;
    std::vector<float> x(size_t(batch) * 9), grad(mlp.parameters().size());
    for (size_t i = 0; i < x.size(); ++i) x[i] = float((i * 37) % 101) / 101.0f - 0.3f;
    double best[3] = {1e30, 1e30, 1e30};
    using Clock = std::chrono::steady_clock;
    for (int r = 0; r < repeat; ++r) {
        double t[3] = {0, 0, 0};
        for (int s = 0; s < steps; ++s) {
            const auto t0 = Clock::now();
            mlp.forwardBatch(x.data(), batch, ws);
            const auto t1 = Clock::now();
            for (int c = 0; c < 3; ++c)
                for (int k = 0; k < batch; ++k) ws.delta(mlp.layers(), c)[k] = ws.value(mlp.layers(), c)[k] - 0.5f;
            std::fill(grad.begin(), grad.end(), 0.0f);
            mlp.backwardBatch(ws, grad.data());
            const auto t2 = Clock::now();
            for (float& g : grad) g *= 1.0f / float(batch);
            adam.step(mlp.parameters(), grad, 1e-4f);
            const auto t3 = Clock::now();
            t[0] += std::chrono::duration<double>(t1 - t0).count();
            t[1] += std::chrono::duration<double>(t2 - t1).count();
            t[2] += std::chrono::duration<double>(t3 - t2).count();
        }
        for (int k = 0; k < 3; ++k) best[k] = std::min(best[k], t[k] / steps * 1e9);
    }
    std::printf("9-9-3 network, batch %d, %d steps, best of %d: forward %.0f ns, backward %.0f ns, Adam %.0f ns per step\n",
                batch, steps, repeat, best[0], best[1], best[2]);
    return 0;
}
