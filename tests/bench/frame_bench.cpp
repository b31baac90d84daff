// One 1080p frame through the runtime, per kernel, on one thread: a G-buffer as an engine holds it (position
// fp32, normal and direction fp16, strided texels; RGBA fp16 out) of the paper's 3x3x3 asset of 9-9-3 fp16
// networks, points coherent in raster order, shaded in 64x64 tiles with nradShadeGBuffer. Portable (no
// intrinsics): it runs natively and under qemu (tests/runtime_standalone builds it for aarch64), where only
// the ratio of a kernel to the scalar one under the same emulator means anything.
//
// Usage: frame_bench [--repeat R]
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <random>
#include <string>
#include <vector>

#include <nrad/format.h>
#include <nrad/nrad.h>

#include "gbuffer_frame.h"

int main(int argc, char** argv) {
    int repeat = 3;
    for (int i = 1; i + 1 < argc; ++i)
        if (std::string(argv[i]) == "--repeat") repeat = std::max(1, std::atoi(argv[++i]));
    nrad::format::Asset a;
    for (int k = 0; k < 3; ++k) {
        a.grid.lower[k] = 0.0f;
        a.grid.upper[k] = 1.0f;
        a.grid.dims[k] = 3;
    }
    a.header.flags = nrad::format::kFlagScatteredRadiance;
    a.topology.outputTransform = nrad::format::OutputTransform::Exponential;
    std::mt19937 rng(1);
    std::uniform_real_distribution<float> u(-0.5f, 0.5f), u01(0.0f, 1.0f);
    for (uint32_t v = 0; v < 27; ++v) a.voxels.push_back({v, 1.0f});
    for (size_t i = 0; i < 27 * a.topology.parameterCount(); ++i) a.weights.push_back(nrad::format::halfToFloat(nrad::format::floatToHalf(u(rng))));
    const std::vector<uint8_t> bytes = nrad::format::encode(a);
    NradAsset asset = nullptr;
    if (nradLoadFromMemory(bytes.data(), bytes.size(), NRAD_LOAD_COPY, &asset, nullptr, 0) != NRAD_OK) return 1;

    using nrad::bench::Texel;
    const size_t w = 1920, h = 1080, frame = w * h;
    std::vector<Texel> texels(frame);
    for (size_t i = 0; i < frame; ++i) {
        const size_t voxel = i * 27 / frame;  // coherent: runs of points per voxel, in raster order
        const float c[3] = {float(voxel % 3), float((voxel / 3) % 3), float(voxel / 9)};
        float n[3], d[3];
        for (int k = 0; k < 3; ++k) {
            texels[i].position[k] = (c[k] + 0.05f + 0.9f * u01(rng)) / 3.0f;
            n[k] = u(rng);
            d[k] = u(rng);
        }
        const float ln = 1.0f / std::sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]), ld = 1.0f / std::sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]);
        for (int k = 0; k < 3; ++k) {
            texels[i].normal[k] = nrad::format::floatToHalf(n[k] * ln);
            texels[i].direction[k] = nrad::format::floatToHalf(d[k] * ld);
        }
    }
    std::vector<uint16_t> rgba(4 * frame);
    std::vector<uint8_t> scratch(nradGetScratchSize());
    std::printf("frame_bench: 1920x1080 G-buffer (position fp32, normal and direction fp16, strided; RGBA fp16 out; "
                "64x64 tiles), 3x3x3 asset of 9-9-3 fp16 networks, 1 thread\n");
    double scalarMs = 0.0;
    for (NradKernel k : {NRAD_KERNEL_SCALAR, NRAD_KERNEL_AVX2, NRAD_KERNEL_AVX512, NRAD_KERNEL_NEON}) {
        if (nradSelectKernel(k) != NRAD_OK) continue;
        double best = 1e30;
        for (int r = 0; r < repeat; ++r) {
            const auto t0 = std::chrono::steady_clock::now();
            for (size_t first = 0; first < frame; first += nrad::bench::kTilePixels) {
                const NradGBuffer g = nrad::bench::describeTile(texels, first, rgba.data());
                if (nradShadeGBuffer(asset, &g, scratch.data(), scratch.size()) != NRAD_OK) return 1;
            }
            best = std::min(best, std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count());
        }
        const char* name = k == NRAD_KERNEL_SCALAR ? "scalar" : k == NRAD_KERNEL_AVX2 ? "avx2" : k == NRAD_KERNEL_AVX512 ? "avx512" : "neon";
        if (k == NRAD_KERNEL_SCALAR) scalarMs = best;
        std::printf("  %-7s %9.2f ms per frame  %6.1fx the scalar kernel\n", name, best, scalarMs / best);
    }
    nradReleaseAsset(asset);
    return 0;
}
