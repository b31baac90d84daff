// Runtime throughput against the machine's own FMA peak, measured in one run.
//
// - FMA peak: 12 independent chains of vector FMAs at the widest width this CPU has (AVX-512, AVX2 or
//   scalar), per thread and on all threads. A 9-9-3 network costs 108 multiply-adds, so the peak in
//   evaluations/s is FMA lanes/s / 108.
// - Network evaluations/s through the public API (nradEvaluateBatch, 64k points per call) on a 3x3x3
//   asset of 9-9-3 fp16 networks, for coherent batches (points sorted by voxel) and incoherent ones
//   (random voxels), per kernel, on 1 thread and on all threads; printed as a fraction of the peak. Coherent
//   batches also through nradEvaluateBatchSoA ("coh. SoA": the same points as nine arrays, nothing to deinterleave).
// - The volume query (nradEvaluateVolumeBatch: the light in the volume, issue 42) on the same points, as a multiple
//   of the surface evaluation's cost.
// - What engines do today, next to it: a trilinear lookup in a grid of L2 spherical-harmonics radiance
//   probes (9 RGB coefficients) holding the same number of bytes as the networks, evaluated in the view
//   direction; lookups/s on one thread.
//
// Usage: runtime_bench [--points N] [--repeat R] [--band B] [--tree-only] [--kernel scalar|avx2|avx512]
// (--tree-only: the kd-tree table alone; --kernel: that kernel for the kd-tree table instead of the best one)
#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <random>
#include <string>
#include <thread>
#include <vector>

#include <nrad/eval.h>
#include <nrad/format.h>
#include <nrad/nrad.h>

#include "fma_peak.h"
#include "gbuffer_frame.h"
#include "../support/test_trees.h"

namespace {

using clock_type = std::chrono::steady_clock;
double seconds(clock_type::time_point a, clock_type::time_point b) { return std::chrono::duration<double>(b - a).count(); }

// ----- network evaluation --------------------------------------------------------------------------------

struct Points {
    std::vector<float> p, n, d;
};

// Points in random voxels of g, `margin` of a voxel away from its faces (0: uniform over the box).
Points makePoints(size_t count, bool coherent, const nrad::format::Grid& g, uint32_t seed, float margin = 0.05f) {
    std::mt19937 rng(seed);
    std::uniform_real_distribution<float> u(0.0f, 1.0f);
    Points pts;
    pts.p.resize(3 * count);
    pts.n.resize(3 * count);
    pts.d.resize(3 * count);
    const uint64_t voxels = g.voxelCount();
    for (size_t i = 0; i < count; ++i) {
        // Coherent: consecutive runs of points in the same voxel (sorted by voxel); incoherent: any voxel.
        uint64_t v = coherent ? (i * voxels) / count : rng() % voxels;
        uint32_t c[3] = {uint32_t(v % g.dims[0]), uint32_t((v / g.dims[0]) % g.dims[1]), uint32_t(v / (g.dims[0] * g.dims[1]))};
        for (int k = 0; k < 3; ++k) {
            float size = (g.upper[k] - g.lower[k]) / float(g.dims[k]);
            pts.p[3 * i + size_t(k)] = g.lower[k] + size * (float(c[k]) + margin + (1.0f - 2.0f * margin) * u(rng));
        }
        float z = 2.0f * u(rng) - 1.0f, a = 6.2831853f * u(rng), r = std::sqrt(1.0f - z * z);
        pts.n[3 * i] = r * std::cos(a);
        pts.n[3 * i + 1] = r * std::sin(a);
        pts.n[3 * i + 2] = z;
        z = 2.0f * u(rng) - 1.0f, a = 6.2831853f * u(rng), r = std::sqrt(1.0f - z * z);
        pts.d[3 * i] = r * std::cos(a);
        pts.d[3 * i + 1] = r * std::sin(a);
        pts.d[3 * i + 2] = z;
    }
    return pts;
}

// The points as nradEvaluateBatchSoA's nine input arrays.
struct SoaPoints {
    std::vector<float> a[9];
};
SoaPoints toSoa(const Points& pts) {
    SoaPoints s;
    const size_t count = pts.p.size() / 3;
    const std::vector<float>* src[3] = {&pts.p, &pts.n, &pts.d};
    for (int v = 0; v < 3; ++v)
        for (int k = 0; k < 3; ++k) {
            std::vector<float>& a = s.a[3 * v + k];
            a.resize(count);
            for (size_t i = 0; i < count; ++i) a[i] = (*src[v])[3 * i + size_t(k)];
        }
    return s;
}

// volume: nradEvaluateVolumeBatch (the light in the volume at the points and normals) instead of nradEvaluateBatch;
// soa: nradEvaluateBatchSoA on these arrays instead.
double evaluationsPerSecond(NradAsset asset, const Points& pts, int threads, int repeat, bool volume = false,
                            const SoaPoints* soa = nullptr) {
    const size_t count = pts.p.size() / 3, batch = 65536;
    // One thread runs in the caller: a new thread per repetition cost up to 10-15% of a run of --points 65536.
    std::vector<std::vector<float>> out(size_t(threads), std::vector<float>(3 * batch, 0.0f));
    double best = 0.0;
    for (int rep = 0; rep < repeat; ++rep) {
        std::atomic<size_t> next{0};
        auto work = [&](int t) {
            for (size_t b; (b = next.fetch_add(batch)) < count;) {
                size_t n = std::min(batch, count - b);
                if (soa) {
                    float* o = out[size_t(t)].data();
                    NradBatchSoA q{};
                    q.px = &soa->a[0][b], q.py = &soa->a[1][b], q.pz = &soa->a[2][b];
                    q.nx = &soa->a[3][b], q.ny = &soa->a[4][b], q.nz = &soa->a[5][b];
                    q.dx = &soa->a[6][b], q.dy = &soa->a[7][b], q.dz = &soa->a[8][b];
                    q.r = o, q.g = o + batch, q.b = o + 2 * batch;
                    nradEvaluateBatchSoA(asset, n, &q);
                } else if (volume) nradEvaluateVolumeBatch(asset, n, &pts.p[3 * b], &pts.n[3 * b], out[size_t(t)].data(), nullptr);
                else nradEvaluateBatch(asset, n, &pts.p[3 * b], &pts.n[3 * b], &pts.d[3 * b], out[size_t(t)].data(), nullptr);
            }
        };
        auto t0 = clock_type::now();
        if (threads == 1) {
            work(0);
        } else {
            std::vector<std::thread> pool;
            for (int t = 0; t < threads; ++t) pool.emplace_back(work, t);
            for (auto& t : pool) t.join();
        }
        best = std::max(best, double(count) / seconds(t0, clock_type::now()));
    }
    return best;
}

// ----- L2 SH probe grid ---------------------------------------------------------------------------------

struct ProbeGrid {
    int dims[3];
    float lower[3], upper[3];
    std::vector<float> coeffs;  // per probe: 9 SH coefficients x RGB = 27 floats
};

inline void shBasis(const float d[3], float y[9]) {
    y[0] = 0.282095f;
    y[1] = 0.488603f * d[1];
    y[2] = 0.488603f * d[2];
    y[3] = 0.488603f * d[0];
    y[4] = 1.092548f * d[0] * d[1];
    y[5] = 1.092548f * d[1] * d[2];
    y[6] = 0.315392f * (3.0f * d[2] * d[2] - 1.0f);
    y[7] = 1.092548f * d[0] * d[2];
    y[8] = 0.546274f * (d[0] * d[0] - d[1] * d[1]);
}

void probeLookup(const ProbeGrid& g, const float p[3], const float d[3], float rgb[3]) {
    int c[3];
    float f[3];
    for (int k = 0; k < 3; ++k) {
        float t = (p[k] - g.lower[k]) / (g.upper[k] - g.lower[k]) * float(g.dims[k] - 1);
        t = std::min(std::max(t, 0.0f), float(g.dims[k] - 1) - 1e-4f);
        c[k] = int(t);
        f[k] = t - float(c[k]);
    }
    float blended[27] = {};
    for (int corner = 0; corner < 8; ++corner) {
        int dx = corner & 1, dy = (corner >> 1) & 1, dz = corner >> 2;
        float w = (dx ? f[0] : 1 - f[0]) * (dy ? f[1] : 1 - f[1]) * (dz ? f[2] : 1 - f[2]);
        const float* src = &g.coeffs[size_t(((c[2] + dz) * g.dims[1] + (c[1] + dy)) * g.dims[0] + (c[0] + dx)) * 27];
        for (int i = 0; i < 27; ++i) blended[i] += w * src[i];
    }
    float y[9];
    shBasis(d, y);
    for (int ch = 0; ch < 3; ++ch) {
        float s = 0.0f;
        for (int i = 0; i < 9; ++i) s += blended[ch * 9 + i] * y[i];
        rgb[ch] = std::max(0.0f, s);
    }
}

}  // namespace

int main(int argc, char** argv) {
    size_t points = 2'000'000;
    int repeat = 3;
    float band = 0.0f;  // --band B: a blended asset (format 2.1) with that band
    for (int i = 1; i + 1 < argc; ++i) {
        if (std::string(argv[i]) == "--points") points = size_t(std::atol(argv[++i]));
        else if (std::string(argv[i]) == "--repeat") repeat = std::max(1, std::atoi(argv[++i]));
        else if (std::string(argv[i]) == "--band") band = std::min(0.5f, std::max(0.0f, float(std::atof(argv[++i]))));
    }
    bool treeOnly = false;  // --tree-only: the kd-tree table alone
    NradKernel treeKernel = NRAD_KERNEL_AUTO;
    for (int i = 1; i < argc; ++i) {
        const std::string arg = argv[i];
        treeOnly = treeOnly || arg == "--tree-only";
        if (arg == "--kernel" && i + 1 < argc) {
            const std::string k = argv[++i];
            treeKernel = k == "scalar" ? NRAD_KERNEL_SCALAR : k == "avx2" ? NRAD_KERNEL_AVX2 : k == "avx512" ? NRAD_KERNEL_AVX512 : NRAD_KERNEL_AUTO;
        }
    }
    const int hw = int(std::max(1u, std::thread::hardware_concurrency()));

    // The paper's configuration: 3x3x3 voxels, 9-9-3 networks, fp16.
    nrad::format::Asset a;
    for (int k = 0; k < 3; ++k) {
        a.grid.lower[k] = 0.0f;
        a.grid.upper[k] = 1.0f;
        a.grid.dims[k] = 3;
    }
    std::mt19937 rng(1);
    std::uniform_real_distribution<float> u(-0.5f, 0.5f);
    for (uint32_t v = 0; v < 27; ++v) a.voxels.push_back({v, 1.0f});
    for (size_t i = 0; i < 27 * a.topology.parameterCount(); ++i) a.weights.push_back(u(rng));
    // The light in the volume (issue 42): networks of the same cells, queried at points and normals.
    for (uint32_t v = 0; v < 27; ++v) a.volumeVoxels.push_back({v, 1.0f});
    for (size_t i = 0; i < 27 * a.topology.parameterCount(); ++i) a.volumeWeights.push_back(u(rng));
    a.topology.outputTransform = std::getenv("NRAD_BENCH_LINEAR") ? nrad::format::OutputTransform::ClampedLinear : nrad::format::OutputTransform::Exponential;
    if (band > 0.0f) {
        a.header.flags |= nrad::format::kFlagBlended;
        a.grid.blendBand = band;
    }
    std::vector<uint8_t> bytes = nrad::format::encode(a);
    NradAsset asset = nullptr;
    if (nradLoadFromMemory(bytes.data(), bytes.size(), NRAD_LOAD_COPY, &asset, nullptr, 0) != NRAD_OK) return 1;
    const double networkBytes = 27.0 * 240.0;

    std::printf("runtime_bench: %zu points, 3x3x3 voxels of 9-9-3 fp16 (%.0f bytes of weights), blend band %g, %d hardware threads\n",
                points, networkBytes, double(band), hw);
    Points coherent = makePoints(points, true, a.grid, 2), incoherent = makePoints(points, false, a.grid, 3);
    const SoaPoints coherentSoa = toSoa(coherent);
    for (int threads : {1, hw}) {
        if (treeOnly) break;
        // The peak of the widest vectors this CPU has, and of AVX2's, measured now; each kernel is also
        // given as a fraction of the peak of its own width.
        const int widest = nradKernelSupported(NRAD_KERNEL_AVX512) ? 16 : 8;
        const double peak = fma_peak::fmaPeak(threads, widest),
                     peak256 = widest == 16 ? fma_peak::fmaPeak(threads, 8) : peak;
        std::printf("\n%d thread(s): FMA peak %.2f G lane-FMA/s (%d-wide vectors) = %.1f M evaluations/s at 108 FMA each; "
                    "8-wide: %.2f G lane-FMA/s\n",
                    threads, peak * 1e-9, widest, peak / 108.0 * 1e-6, peak256 * 1e-9);
        std::printf("  %-8s %-11s %14s %10s %14s\n", "kernel", "batch", "M evals/s", "of peak", "of own width");
        for (NradKernel k : {NRAD_KERNEL_SCALAR, NRAD_KERNEL_AVX2, NRAD_KERNEL_AVX512}) {
            if (nradSelectKernel(k) != NRAD_OK) continue;
            const char* name = k == NRAD_KERNEL_SCALAR ? "scalar" : k == NRAD_KERNEL_AVX2 ? "avx2" : "avx512";
            const double own = k == NRAD_KERNEL_AVX512 ? peak : peak256;
            auto row = [&](const char* batch, double e) {
                std::printf("  %-8s %-11s %14.1f %9.1f%% %13.1f%%\n", name, batch, e * 1e-6, 100.0 * e * 108.0 / peak,
                            100.0 * e * 108.0 / own);
            };
            row("coherent", evaluationsPerSecond(asset, coherent, threads, repeat));
            row("incoherent", evaluationsPerSecond(asset, incoherent, threads, repeat));
            row("coh. SoA", evaluationsPerSecond(asset, coherent, threads, repeat, false, &coherentSoa));
        }
        nradSelectKernel(NRAD_KERNEL_AUTO);
        // The volume query against the surface evaluation, same kernel (the best), same points (goal: <= 2x the cost).
        for (int coh = 1; coh >= 0; --coh) {
            const double surface = evaluationsPerSecond(asset, coh ? coherent : incoherent, threads, repeat);
            const double volume = evaluationsPerSecond(asset, coh ? coherent : incoherent, threads, repeat, true);
            std::printf("  volume query (nradEvaluateVolumeBatch), %s: %.1f M/s, %.2fx the cost of a surface evaluation (%.1f M/s)\n",
                        coh ? "coherent" : "incoherent", volume * 1e-6, surface / volume, surface * 1e-6);
        }
    }

    // A G-buffer as an engine holds it: a 1920 x 1080 frame of texels (position fp32, normal and direction
    // fp16, padded), the coherent points above in raster order, shaded in 64 x 64 tiles through
    // nradShadeGBuffer (evaluate only) into RGBA fp16, each call with its own scratch; against nradEvaluateBatch
    // on the same points in fp32, interleaved, in the same tiles.
    if (!treeOnly) {
        using nrad::bench::Texel;
        const size_t w = 1920, h = 1080, frame = w * h;
        Points pts = makePoints(frame, true, a.grid, 7);
        std::vector<Texel> texels(frame);
        for (size_t i = 0; i < frame; ++i)
            for (int k = 0; k < 3; ++k) {
                texels[i].position[k] = pts.p[3 * i + size_t(k)];
                texels[i].normal[k] = nrad::format::floatToHalf(pts.n[3 * i + size_t(k)]);
                texels[i].direction[k] = nrad::format::floatToHalf(pts.d[3 * i + size_t(k)]);
                pts.n[3 * i + size_t(k)] = nrad::format::halfToFloat(texels[i].normal[k]);
                pts.d[3 * i + size_t(k)] = nrad::format::halfToFloat(texels[i].direction[k]);
            }
        std::vector<uint16_t> rgba(4 * frame);
        std::vector<float> rgb(3 * 4096);
        std::vector<uint8_t> scratch(nradGetScratchSize());
        double gbufferBest = 0.0, batchBest = 0.0;
        for (int r = 0; r < repeat; ++r) {
            auto t0 = clock_type::now();
            for (size_t first = 0; first < frame; first += nrad::bench::kTilePixels) {
                const NradGBuffer g = nrad::bench::describeTile(texels, first, rgba.data());
                nradShadeGBuffer(asset, &g, scratch.data(), scratch.size());
            }
            auto t1 = clock_type::now();
            for (size_t first = 0; first < frame; first += 4096) {
                const size_t n = std::min<size_t>(4096, frame - first);
                nradEvaluateBatch(asset, n, &pts.p[3 * first], &pts.n[3 * first], &pts.d[3 * first], rgb.data(), nullptr);
            }
            auto t2 = clock_type::now();
            gbufferBest = std::max(gbufferBest, double(frame) / seconds(t0, t1));
            batchBest = std::max(batchBest, double(frame) / seconds(t1, t2));
        }
        std::printf("\nG-buffer 1920x1080 (position fp32, normal and direction fp16, strided; RGBA fp16 out; 64x64 tiles), "
                    "1 thread, kernel %d:\n  nradShadeGBuffer %.1f M points/s (%.2f ms per frame); nradEvaluateBatch on the "
                    "same points in fp32 %.1f M points/s (%.2f ms): %.0f%%\n",
                    int(nradActiveKernel()), gbufferBest * 1e-6, 1e3 * double(frame) / gbufferBest, batchBest * 1e-6,
                    1e3 * double(frame) / batchBest, 100.0 * gbufferBest / batchBest);
        // The same frame shaded with material terms (an NradSurface per pixel, random base colours, metallic 0 or
        // 1, roughness, emission) by an asset of demodulated scattered radiance: the whole shading contract.
        nrad::format::Asset contract = a;
        contract.header.flags |= nrad::format::kFlagScatteredRadiance | nrad::format::kFlagDemodulated;
        const std::vector<uint8_t> contractBytes = nrad::format::encode(contract);
        NradAsset shaded = nullptr;
        if (nradLoadFromMemory(contractBytes.data(), contractBytes.size(), NRAD_LOAD_COPY, &shaded, nullptr, 0) != NRAD_OK) return 1;
        std::uniform_real_distribution<float> u01(0.0f, 1.0f);
        std::vector<NradSurface> surfaces(frame);
        for (NradSurface& m : surfaces)
            m = {{u01(rng), u01(rng), u01(rng)}, u01(rng) < 0.3f ? 1.0f : 0.0f, u01(rng), 1.0f, {0.1f * u01(rng), 0.0f, 0.0f}};
        double shadedBest = 0.0;
        for (int r = 0; r < repeat; ++r) {
            auto t0 = clock_type::now();
            for (size_t first = 0; first < frame; first += nrad::bench::kTilePixels) {
                const NradGBuffer g = nrad::bench::describeTile(texels, first, rgba.data(), surfaces.data());
                nradShadeGBuffer(shaded, &g, scratch.data(), scratch.size());
            }
            shadedBest = std::max(shadedBest, double(frame) / seconds(t0, clock_type::now()));
        }
        std::printf("  shaded with an NradSurface per pixel (demodulated scattered radiance): %.1f M points/s (%.2f ms per frame)\n",
                    shadedBest * 1e-6, 1e3 * double(frame) / shadedBest);
        // The same shading through nradShadeBatch from the fp32 interleaved arrays of the batch rows above.
        double batchShadedBest = 0.0;
        for (int r = 0; r < repeat; ++r) {
            auto t0 = clock_type::now();
            for (size_t first = 0; first < frame; first += nrad::bench::kTilePixels) {
                const size_t n = std::min(nrad::bench::kTilePixels, frame - first);
                nradShadeBatch(shaded, n, &pts.p[3 * first], &pts.n[3 * first], &pts.d[3 * first], &surfaces[first], rgb.data(), nullptr);
            }
            batchShadedBest = std::max(batchShadedBest, double(frame) / seconds(t0, clock_type::now()));
        }
        std::printf("  nradShadeBatch, the same shading from fp32 interleaved arrays: %.1f M points/s (%.2f ms per frame)\n",
                    batchShadedBest * 1e-6, 1e3 * double(frame) / batchShadedBest);
        nradReleaseAsset(shaded);
    }

    // One point per call (nradEvaluate), as a shader's per-pixel fallback or a gameplay query would: the rate
    // must not fall with the number of networks. Grids of 3^3, 7^3 and 16^3 occupied voxels, incoherent points.
    // Per kernel, so that AUTO's choice can be checked against the others on this path too.
    std::vector<NradKernel> singleKernels;
    for (NradKernel k : {NRAD_KERNEL_SCALAR, NRAD_KERNEL_AVX2, NRAD_KERNEL_AVX512})
        if (nradKernelSupported(k)) singleKernels.push_back(k);
    if (!treeOnly) {
        std::printf("\nnradEvaluate, one point per call, 1 thread, incoherent points, M points/s (AUTO: kernel %d):\n",
                    int(nradActiveKernel()));
        std::printf("  %-10s %10s", "grid", "networks");
        for (NradKernel k : singleKernels)
            std::printf(" %10s", k == NRAD_KERNEL_SCALAR ? "scalar" : k == NRAD_KERNEL_AVX2 ? "avx2" : "avx512");
        std::printf("\n");
    }
    for (uint32_t dim : {3u, 7u, 16u}) {
        if (treeOnly) break;
        nrad::format::Asset big = a;
        big.voxels.clear();
        big.weights.clear();
        for (int k = 0; k < 3; ++k) big.grid.dims[k] = dim;
        for (uint32_t v = 0; v < dim * dim * dim; ++v) big.voxels.push_back({v, 1.0f});
        for (size_t i = 0; i < big.voxels.size() * big.topology.parameterCount(); ++i) big.weights.push_back(u(rng));
        const std::vector<uint8_t> bigBytes = nrad::format::encode(big);
        NradAsset h = nullptr;
        if (nradLoadFromMemory(bigBytes.data(), bigBytes.size(), NRAD_LOAD_COPY, &h, nullptr, 0) != NRAD_OK) return 1;
        const size_t n = std::min<size_t>(points, 200'000);
        Points single = makePoints(n, false, big.grid, 5);
        std::printf("  %-10s %10zu", (std::to_string(dim) + "^3").c_str(), big.voxels.size());
        for (NradKernel k : singleKernels) {
            nradSelectKernel(k);
            double best = 0.0;
            for (int r = 0; r < repeat; ++r) {
                float rgb[3];
                float sink = 0.0f;
                auto t0 = clock_type::now();
                for (size_t i = 0; i < n; ++i) {
                    nradEvaluate(h, &single.p[3 * i], &single.n[3 * i], &single.d[3 * i], rgb, nullptr);
                    sink += rgb[0];
                }
                best = std::max(best, double(n) / seconds(t0, clock_type::now()));
                if (sink < 0.0f) std::printf("impossible\n");
            }
            std::printf(" %10.2f", best * 1e-6);
        }
        std::printf("\n");
        nradSelectKernel(NRAD_KERNEL_AUTO);
        nradReleaseAsset(h);
    }

    // SH probe grid with the same bytes as the networks: 27 fp32 coefficients = 108 bytes per probe.
    int probesPerAxis = int(std::lround(std::cbrt(networkBytes / 108.0)));
    ProbeGrid g{{probesPerAxis, probesPerAxis, probesPerAxis}, {0, 0, 0}, {1, 1, 1}, {}};
    g.coeffs.resize(size_t(probesPerAxis * probesPerAxis * probesPerAxis) * 27);
    for (float& c : g.coeffs) c = u(rng);
    std::vector<float> out(3);
    double best = 0.0;
    for (int rep = 0; rep < repeat; ++rep) {
        auto t0 = clock_type::now();
        float acc = 0.0f;
        for (size_t i = 0; i < points; ++i) {
            probeLookup(g, &incoherent.p[3 * i], &incoherent.d[3 * i], out.data());
            acc += out[0];
        }
        fma_peak::gSink = fma_peak::gSink + acc;
        best = std::max(best, double(points) / seconds(t0, clock_type::now()));
    }
    if (treeKernel != NRAD_KERNEL_AUTO && nradSelectKernel(treeKernel) != NRAD_OK) return 1;
    NradKernel auto_ = nradActiveKernel();
    double network = evaluationsPerSecond(asset, incoherent, 1, repeat);

    // The kd-tree partition (format 2.2): what locating through the tree costs next to a whole evaluation.
    // Assets of 9-9-3 fp16 networks on a 128^3 lattice, one tree each (tests/support/test_trees.h: random
    // planes, leaves of many sizes, every leaf a network), incoherent points, one thread: evaluations/s through the public API (locate
    // included), and in the same run the locate alone (eval::Partition::supports + keepOccupied, what
    // the runtime calls per point) over the same points.
    // ("scalar share": evaluation time / that locate's time, which the vector kernels now mostly skip.) Then what
    // the tree costs over the grid's nearly free vector locate with as many networks: 1 - tree rate / grid rate.
    // Then coherent batches: the same points sorted by their leaf (for the grid, by their voxel), as a
    // G-buffer's runs of pixels on one surface are: vectors inside one leaf are located in registers.
    // Points uniform over the box (the tables above keep theirs 5% of a voxel away from the 3x3x3 grid's faces, which
    // would keep the grid of 27 voxels out of its own blending bands).
    const Points uniform = makePoints(points, false, a.grid, 3, 0.0f);
    std::printf("\nkd-tree partition, 1 thread, incoherent points, kernel %d (blend band %g):\n", int(auto_), double(band));
    std::printf("  %8s %6s %10s %14s %14s %12s %14s %10s %14s %14s %10s\n", "leaves", "depth", "bytes", "M evals/s",
                "M locates/s", "scalar share", "grid M evals/s", "over grid", "sorted: tree", "sorted: grid", "over grid");
    for (uint32_t leaves : {27u, 512u, 4096u}) {
        nrad::format::Asset t;
        for (int k = 0; k < 3; ++k) {
            t.grid.lower[k] = 0.0f;
            t.grid.upper[k] = 1.0f;
            t.grid.dims[k] = 128;
        }
        t.topology = a.topology;
        t.header.flags = nrad::format::kFlagTree | (band > 0.0f ? nrad::format::kFlagBlended : 0u);
        t.grid.blendBand = band;
        t.tree = nrad::test::randomTree(t.grid.dims, leaves, leaves);  // random planes, leaves of many sizes
        uint32_t leafCount = 0;
        if (!nrad::format::validateTree(t.grid.dims, t.tree, leafCount)) return 1;
        uint32_t depth = 0;
        {
            std::vector<std::pair<uint32_t, uint32_t>> stack = {{0, 0}};
            while (!stack.empty()) {
                auto [n, d] = stack.back();
                stack.pop_back();
                depth = std::max(depth, d);
                if (t.tree[n].axis != nrad::format::kTreeLeaf) {
                    stack.push_back({t.tree[n].child, d + 1});
                    stack.push_back({t.tree[n].child + 1, d + 1});
                }
            }
        }
        for (uint32_t v = 0; v < leafCount; ++v) t.voxels.push_back({v, 1.0f});
        for (size_t i = 0; i < leafCount * t.topology.parameterCount(); ++i) t.weights.push_back(u(rng));
        const std::vector<uint8_t> tb = nrad::format::encode(t);
        NradAsset ta = nullptr;
        if (nradLoadFromMemory(tb.data(), tb.size(), NRAD_LOAD_COPY, &ta, nullptr, 0) != NRAD_OK) return 1;
        const double evals = evaluationsPerSecond(ta, uniform, 1, repeat);
        // The same networks on the uniform grid of as many voxels (16^3 = 4096, 8^3 = 512, 3^3 = 27).
        nrad::format::Asset g = t;
        g.header.flags &= ~nrad::format::kFlagTree;
        g.tree.clear();
        const uint32_t side = uint32_t(std::lround(std::cbrt(double(leafCount))));
        for (int k = 0; k < 3; ++k) g.grid.dims[k] = side;
        g.voxels.resize(size_t(side) * side * side);
        g.weights.resize(g.voxels.size() * g.topology.parameterCount());
        const std::vector<uint8_t> gb = nrad::format::encode(g);
        NradAsset ga = nullptr;
        if (nradLoadFromMemory(gb.data(), gb.size(), NRAD_LOAD_COPY, &ga, nullptr, 0) != NRAD_OK) return 1;
        const double gridEvals = evaluationsPerSecond(ga, uniform, 1, repeat);
        nrad::format::Asset decoded;
        nrad::format::decode(tb.data(), tb.size(), decoded);
        const nrad::eval::Partition part(decoded);
        double bestLocate = 0.0;
        for (int rep = 0; rep < repeat; ++rep) {
            auto t0 = clock_type::now();
            size_t acc = 0;
            for (size_t i = 0; i < points; ++i) {
                nrad::eval::Support sup[nrad::eval::kMaxSupports];
                int c = part.supports(&uniform.p[3 * i], sup);
                c = nrad::eval::keepOccupied(sup, c, [](int64_t) { return true; });
                acc += size_t(c) + (c > 0 ? size_t(sup[0].voxel) : 0);
            }
            fma_peak::gSink = fma_peak::gSink + float(acc);
            bestLocate = std::max(bestLocate, double(points) / seconds(t0, clock_type::now()));
        }
        // Sorted by cell, stably: runs of points in one leaf (one voxel).
        auto sortedBy = [&](const nrad::eval::Partition& by) {
            std::vector<std::pair<int64_t, size_t>> keys(points);
            for (size_t i = 0; i < points; ++i) keys[i] = {by.cellOf(&uniform.p[3 * i]), i};
            std::sort(keys.begin(), keys.end());
            Points sorted;
            for (const auto& [cell, i] : keys) {
                (void)cell;
                sorted.p.insert(sorted.p.end(), &uniform.p[3 * i], &uniform.p[3 * i] + 3);
                sorted.n.insert(sorted.n.end(), &uniform.n[3 * i], &uniform.n[3 * i] + 3);
                sorted.d.insert(sorted.d.end(), &uniform.d[3 * i], &uniform.d[3 * i] + 3);
            }
            return sorted;
        };
        nrad::format::Asset gridDecoded;
        nrad::format::decode(gb.data(), gb.size(), gridDecoded);
        const double sortedTree = evaluationsPerSecond(ta, sortedBy(part), 1, repeat);
        const double sortedGrid = evaluationsPerSecond(ga, sortedBy(nrad::eval::Partition(gridDecoded)), 1, repeat);
        std::printf("  %8u %6u %10zu %14.1f %14.1f %11.1f%% %14.1f %9.0f%% %14.1f %14.1f %9.0f%%\n", leafCount, depth,
                    tb.size(), evals * 1e-6, bestLocate * 1e-6, 100.0 * evals / bestLocate, gridEvals * 1e-6,
                    100.0 * (1.0 - evals / gridEvals), sortedTree * 1e-6, sortedGrid * 1e-6, 100.0 * (1.0 - sortedTree / sortedGrid));
        nradReleaseAsset(ta);
        nradReleaseAsset(ga);
    }
    std::printf("\nL2 SH probe grid of the same bytes (%d^3 probes x 27 fp32): %.1f M trilinear lookups/s on 1 thread; "
                "networks (kernel %d, incoherent): %.1f M/s = %.2fx the probe lookup's rate\n",
                probesPerAxis, best * 1e-6, int(auto_), network * 1e-6, network / best);
    nradReleaseAsset(asset);
    return 0;
}
