// One 1080p frame through the runtime, per kernel and per G-buffer format, on one thread: the paper's 3x3x3
// asset of 9-9-3 fp16 networks, points coherent in raster order, shaded in 64x64 tiles with nradShadeGBuffer,
// and the same points through nradEvaluateBatch (fp32 interleaved, the same tiles: each kernel's batch rate, which
// a G-buffer that needs no shading should come close to). Formats: the engine texel of gbuffer_frame.h (position
// fp32, normal and direction fp16, 28-byte stride; RGBA fp16 out), the same with directions from an eye position
// and normals normalised on input, the same shaded with an NradSurface per pixel, fp32 attributes in separate
// packed arrays into RGBA and RGB fp32, and fp16 attributes (positions too) into packed RGB fp16: every input
// and output path of the kernels' G-buffer code. Portable (no intrinsics): it runs natively and under qemu
// (tests/runtime_standalone builds it for aarch64), where only the ratio of a kernel to the scalar one under
// the same emulator means anything.
//
// Usage: frame_bench [--repeat R] [--no-scalar]
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

namespace {

struct Half4 {
    uint16_t v[4];  // x y z and a pad
};

// One G-buffer format of the frame: a tile's description from its first texel.
struct Format {
    const char* name;
    NradGBuffer (*describe)(size_t first);
};

// The frame in every layout (the same values: fp16 attributes' fp32 copies are their exact conversions).
struct Frame {
    std::vector<nrad::bench::Texel> texels;
    std::vector<float> p, n, d;  // fp32, interleaved
    std::vector<Half4> p16, n16, d16;
    std::vector<NradSurface> surfaces;
    std::vector<uint8_t> out;  // room for RGBA fp32
    float eye[3] = {0.5f, 0.5f, 4.0f};
};
Frame gFrame;

size_t tileCount(size_t first) { return std::min(nrad::bench::kTilePixels, gFrame.texels.size() - first); }

NradGBuffer texelTile(size_t first) {
    return nrad::bench::describeTile(gFrame.texels, first, reinterpret_cast<uint16_t*>(gFrame.out.data()));
}

NradGBuffer eyeTile(size_t first) {
    NradGBuffer g = texelTile(first);
    g.flags = NRAD_GBUFFER_EYE;  // normals normalised on input, directions from the eye
    for (int k = 0; k < 3; ++k) g.eye[k] = gFrame.eye[k];
    return g;
}

NradGBuffer shadedTile(size_t first) {
    return nrad::bench::describeTile(gFrame.texels, first, reinterpret_cast<uint16_t*>(gFrame.out.data()),
                                     gFrame.surfaces.data());
}

NradGBuffer fp32Tile(size_t first, uint32_t channels) {
    NradGBuffer g;
    std::memset(&g, 0, sizeof g);
    g.structSize = sizeof g;
    g.flags = NRAD_GBUFFER_UNIT_VECTORS;
    g.count = tileCount(first);
    g.position = {&gFrame.p[3 * first], 0, NRAD_FORMAT_F32};
    g.normal = {&gFrame.n[3 * first], 0, NRAD_FORMAT_F32};
    g.direction = {&gFrame.d[3 * first], 0, NRAD_FORMAT_F32};
    g.output = gFrame.out.data() + 4 * channels * first;
    g.outputFormat = NRAD_FORMAT_F32;
    g.outputChannels = channels;
    return g;
}

NradGBuffer fp32RgbaTile(size_t first) { return fp32Tile(first, 4); }
NradGBuffer fp32RgbTile(size_t first) { return fp32Tile(first, 3); }

NradGBuffer fp16RgbTile(size_t first) {
    NradGBuffer g;
    std::memset(&g, 0, sizeof g);
    g.structSize = sizeof g;
    g.flags = NRAD_GBUFFER_UNIT_VECTORS;
    g.count = tileCount(first);
    g.position = {&gFrame.p16[first], sizeof(Half4), NRAD_FORMAT_F16};
    g.normal = {&gFrame.n16[first], sizeof(Half4), NRAD_FORMAT_F16};
    g.direction = {&gFrame.d16[first], sizeof(Half4), NRAD_FORMAT_F16};
    g.output = gFrame.out.data() + 6 * first;
    g.outputFormat = NRAD_FORMAT_F16;
    g.outputChannels = 3;
    return g;
}

const Format kFormats[] = {
    {"texel f32/f16/f16 -> RGBA f16", texelTile},
    {"  eye directions, normalised", eyeTile},
    {"  shaded (NradSurface)", shadedTile},
    {"f32 arrays -> RGBA f32", fp32RgbaTile},
    {"f32 arrays -> RGB f32", fp32RgbTile},
    {"f16 (8-byte) -> RGB f16", fp16RgbTile},
};

using clock_type = std::chrono::steady_clock;
double ms(clock_type::time_point a, clock_type::time_point b) {
    return std::chrono::duration<double, std::milli>(b - a).count();
}

}  // namespace

int main(int argc, char** argv) {
    int repeat = 3;
    bool scalar = true;
    for (int i = 1; i < argc; ++i) {
        if (std::string(argv[i]) == "--repeat" && i + 1 < argc) repeat = std::max(1, std::atoi(argv[++i]));
        if (std::string(argv[i]) == "--no-scalar") scalar = false;
    }
    nrad::format::Asset a;
    for (int k = 0; k < 3; ++k) {
        a.grid.lower[k] = 0.0f;
        a.grid.upper[k] = 1.0f;
        a.grid.dims[k] = 3;
    }
    // Scattered radiance, demodulated: the shaded format applies the whole shading contract (the flags change
    // nothing for the others).
    a.header.flags = nrad::format::kFlagScatteredRadiance | nrad::format::kFlagDemodulated;
    a.topology.outputTransform = nrad::format::OutputTransform::Exponential;
    std::mt19937 rng(1);
    std::uniform_real_distribution<float> u(-0.5f, 0.5f), u01(0.0f, 1.0f);
    for (uint32_t v = 0; v < 27; ++v) a.voxels.push_back({v, 1.0f});
    for (size_t i = 0; i < 27 * a.topology.parameterCount(); ++i)
        a.weights.push_back(nrad::format::halfToFloat(nrad::format::floatToHalf(u(rng))));
    const std::vector<uint8_t> bytes = nrad::format::encode(a);
    NradAsset asset = nullptr;
    if (nradLoadFromMemory(bytes.data(), bytes.size(), NRAD_LOAD_COPY, &asset, nullptr, 0) != NRAD_OK) return 1;

    const size_t w = 1920, h = 1080, frame = w * h;
    Frame& f = gFrame;
    f.texels.resize(frame);
    for (size_t i = 0; i < frame; ++i) {
        const size_t voxel = i * 27 / frame;  // coherent: runs of points per voxel, in raster order
        const float c[3] = {float(voxel % 3), float((voxel / 3) % 3), float(voxel / 9)};
        float n[3], d[3];
        for (int k = 0; k < 3; ++k) {
            f.texels[i].position[k] = (c[k] + 0.05f + 0.9f * u01(rng)) / 3.0f;
            n[k] = u(rng);
            d[k] = u(rng);
        }
        const float ln = 1.0f / std::sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]),
                    ld = 1.0f / std::sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]);
        for (int k = 0; k < 3; ++k) {
            f.texels[i].normal[k] = nrad::format::floatToHalf(n[k] * ln);
            f.texels[i].direction[k] = nrad::format::floatToHalf(d[k] * ld);
        }
    }
    f.p.resize(3 * frame);
    f.n.resize(3 * frame);
    f.d.resize(3 * frame);
    f.p16.resize(frame);
    f.n16.resize(frame);
    f.d16.resize(frame);
    f.surfaces.resize(frame);
    for (size_t i = 0; i < frame; ++i) {
        for (int k = 0; k < 3; ++k) {
            f.p[3 * i + size_t(k)] = f.texels[i].position[k];
            f.n[3 * i + size_t(k)] = nrad::format::halfToFloat(f.texels[i].normal[k]);
            f.d[3 * i + size_t(k)] = nrad::format::halfToFloat(f.texels[i].direction[k]);
            f.p16[i].v[k] = nrad::format::floatToHalf(f.texels[i].position[k]);
            f.n16[i].v[k] = f.texels[i].normal[k];
            f.d16[i].v[k] = f.texels[i].direction[k];
        }
        f.surfaces[i] = {{u01(rng), u01(rng), u01(rng)}, u01(rng) < 0.3f ? 1.0f : 0.0f, u01(rng), 1.0f, {0.1f * u01(rng), 0.0f, 0.0f}};
    }
    f.out.resize(16 * frame);
    std::vector<float> rgb(3 * nrad::bench::kTilePixels);
    std::vector<uint8_t> scratch(nradGetScratchSize());

    std::vector<NradKernel> kernels;
    for (NradKernel k : {NRAD_KERNEL_SCALAR, NRAD_KERNEL_AVX2, NRAD_KERNEL_AVX512, NRAD_KERNEL_NEON})
        if (nradKernelSupported(k) && (scalar || k != NRAD_KERNEL_SCALAR)) kernels.push_back(k);
    auto name = [](NradKernel k) {
        return k == NRAD_KERNEL_SCALAR ? "scalar" : k == NRAD_KERNEL_AVX2 ? "avx2" : k == NRAD_KERNEL_AVX512 ? "avx512" : "neon";
    };
    nradSelectKernel(NRAD_KERNEL_AUTO);
    std::printf("frame_bench: 1920x1080 G-buffer, 64x64 tiles, 3x3x3 asset of 9-9-3 fp16 networks, 1 thread, best of %d; "
                "AUTO is %s\n  ms per frame (G-buffer rate / the kernel's own batch rate)\n",
                repeat, name(nradActiveKernel()));
    std::printf("  %-32s", "format");
    for (NradKernel k : kernels) std::printf(" %18s", name(k));
    std::printf("\n");
    // Per kernel, each repetition times the batch call and then every format once, so that a ratio compares frames
    // measured side by side (a shared machine's load drifts); the best of the repetitions is printed.
    constexpr size_t kFormatCount = sizeof kFormats / sizeof kFormats[0];
    std::vector<double> batchMs(kernels.size(), 1e30);
    std::vector<std::vector<double>> formatMs(kernels.size(), std::vector<double>(kFormatCount, 1e30));
    for (size_t i = 0; i < kernels.size(); ++i) {
        nradSelectKernel(kernels[i]);
        for (int r = 0; r < repeat; ++r) {
            auto t0 = clock_type::now();
            for (size_t first = 0; first < frame; first += nrad::bench::kTilePixels)
                if (nradEvaluateBatch(asset, tileCount(first), &f.p[3 * first], &f.n[3 * first], &f.d[3 * first],
                                      rgb.data(), nullptr) != NRAD_OK)
                    return 1;
            batchMs[i] = std::min(batchMs[i], ms(t0, clock_type::now()));
            for (size_t j = 0; j < kFormatCount; ++j) {
                t0 = clock_type::now();
                for (size_t first = 0; first < frame; first += nrad::bench::kTilePixels) {
                    const NradGBuffer g = kFormats[j].describe(first);
                    if (nradShadeGBuffer(asset, &g, scratch.data(), scratch.size()) != NRAD_OK) return 1;
                }
                formatMs[i][j] = std::min(formatMs[i][j], ms(t0, clock_type::now()));
            }
        }
    }
    std::printf("  %-32s", "nradEvaluateBatch (fp32)");
    for (double b : batchMs) std::printf(" %10.2f       ", b);
    std::printf("\n");
    for (size_t j = 0; j < kFormatCount; ++j) {
        std::printf("  %-32s", kFormats[j].name);
        for (size_t i = 0; i < kernels.size(); ++i) std::printf(" %10.2f (%3.0f%%)", formatMs[i][j], 100.0 * batchMs[i] / formatMs[i][j]);
        std::printf("\n");
    }
    if (kernels.front() == NRAD_KERNEL_SCALAR) {  // under an emulator, the one figure that means anything
        std::printf("  the texel format against the scalar kernel:");
        for (size_t i = 1; i < kernels.size(); ++i) std::printf(" %s %.1fx", name(kernels[i]), formatMs[0][0] / formatMs[i][0]);
        std::printf("\n");
    }
    nradSelectKernel(NRAD_KERNEL_AUTO);
    nradReleaseAsset(asset);
    return 0;
}
