// Evaluation allocates nothing (issue 18): operator new is counted for the whole binary, and the scratch
// allocator hook is counted; a thread's first evaluation takes its scratch through the hook, once, and every
// entry point then runs without a single allocation; the scratch goes back through the hook at thread exit.
#include <nrad/format.h>
#include <nrad/nrad.h>
#include <nrad/nrad.hpp>

#include <atomic>
#include <cstdlib>
#include <cstring>
#include <new>
#include <thread>

#include <gtest/gtest.h>

#include "support/random_asset.h"

namespace {
std::atomic<bool> gCounting{false};
std::atomic<size_t> gNews{0};
}  // namespace

void* operator new(size_t bytes) {
    if (gCounting.load(std::memory_order_relaxed)) gNews.fetch_add(1, std::memory_order_relaxed);
    if (void* p = std::malloc(bytes ? bytes : 1)) return p;
    throw std::bad_alloc();
}
void operator delete(void* p) noexcept { std::free(p); }
void operator delete(void* p, size_t) noexcept { std::free(p); }

namespace nrad {
namespace {

struct Hook {
    std::atomic<size_t> allocations{0}, frees{0}, bytes{0};
};

void* countingAllocate(size_t bytes, void* user) {
    auto* h = static_cast<Hook*>(user);
    ++h->allocations;
    h->bytes += bytes;
    return std::malloc(bytes);
}
void countingFree(void* p, void* user) {
    ++static_cast<Hook*>(user)->frees;
    std::free(p);
}

TEST(RuntimeMemory, EvaluationAllocatesNothingAndScratchGoesThroughTheHook) {
    for (float band : {0.0f, 0.125f}) {
        format::Asset a = test::randomAsset({9}, format::WeightEncoding::Float16, format::OutputTransform::Exponential, 9,
                                            glm::uvec3(5, 4, 3), band);
        a.header.flags |= format::kFlagScatteredRadiance | format::kFlagDemodulated;
        const std::vector<uint8_t> bytes = format::encode(a);
        nrad::Asset asset;
        ASSERT_EQ(asset.loadFromMemory(bytes.data(), bytes.size()), NRAD_OK);
        const size_t n = 50000;  // many tiles
        std::vector<float> p(3 * n), nrm(3 * n), d(3 * n), rgb(3 * n);
        std::vector<uint8_t> flags(n);
        std::vector<NradSurface> surfaces(n, NradSurface{{0.5f, 0.5f, 0.5f}, 0.0f, 0.5f, 1.0f, {0.1f, 0.0f, 0.0f}});
        for (size_t i = 0; i < n; ++i)
            for (int k = 0; k < 3; ++k) {
                p[3 * i + size_t(k)] = a.grid.lower[k] + (a.grid.upper[k] - a.grid.lower[k]) * float((i * (k + 3) * 7919) % 1000) / 999.0f;
                nrm[3 * i + size_t(k)] = k == 2 ? 1.0f : 0.0f;
                d[3 * i + size_t(k)] = k == 1 ? 1.0f : 0.0f;
            }
        // A G-buffer of the same points into `output` (fp32 RGB or fp16 RGBA), shaded when `shaded`.
        auto describe = [&](void* output, uint32_t format, uint32_t channels, const NradSurface* shaded) {
            NradGBuffer g;
            std::memset(&g, 0, sizeof g);
            g.structSize = sizeof g;
            g.count = n;
            g.position = {p.data(), 0, NRAD_FORMAT_F32};
            g.normal = {nrm.data(), 0, NRAD_FORMAT_F32};
            g.direction = {d.data(), 0, NRAD_FORMAT_F32};
            g.surfaces = shaded;
            g.output = output;
            g.outputFormat = format;
            g.outputChannels = channels;
            return g;
        };
        Hook hook;
        nradSetAllocator(countingAllocate, countingFree, &hook);
        size_t news = 0;
        std::thread worker([&] {
            gNews = 0;
            gCounting = true;
            int* volatile probe = new int(1);  // the counter counts (volatile: the allocation is not elided)
            delete probe;
            EXPECT_EQ(gNews.load(), 1u);
            gNews = 0;
            for (int repeat = 0; repeat < 2; ++repeat) {
                EXPECT_EQ(asset.evaluateBatch(n, p.data(), nrm.data(), d.data(), rgb.data(), flags.data()), NRAD_OK);
                EXPECT_EQ(asset.shadeBatch(n, p.data(), nrm.data(), d.data(), surfaces.data(), rgb.data(), flags.data()), NRAD_OK);
                float one[3];
                for (size_t i = 0; i < 1000; ++i) EXPECT_EQ(asset.evaluate(&p[3 * i], &nrm[3 * i], &d[3 * i], one), NRAD_OK);
                const NradGBuffer gb = describe(rgb.data(), NRAD_FORMAT_F32, 3, nullptr);  // the thread's scratch
                EXPECT_EQ(nradShadeGBuffer(asset.get(), &gb, nullptr, 0), NRAD_OK);
            }
            gCounting = false;
            news = gNews;
        });
        worker.join();
        nradSetAllocator(nullptr, nullptr, nullptr);
        EXPECT_EQ(news, 0u) << "operator new during evaluation, band " << band;
        EXPECT_EQ(hook.allocations.load(), 1u) << "one scratch block for the thread, whichever entry points it uses";
        EXPECT_EQ(hook.bytes.load(), nradGetScratchSize());
        EXPECT_EQ(hook.frees.load(), 1u) << "released at thread exit";
        EXPECT_LT(nradGetScratchSize(), size_t(1) << 20) << "bounded, whatever the batch size";

        // With the caller's scratch, a G-buffer call allocates nothing at all, not even the thread's scratch.
        std::vector<uint8_t> scratch(nradGetScratchSize());
        std::vector<uint16_t> half(4 * n);
        const NradGBuffer g = describe(half.data(), NRAD_FORMAT_F16, 4, surfaces.data());
        Hook untouched;
        nradSetAllocator(countingAllocate, countingFree, &untouched);
        std::thread gbuffer([&] {
            gNews = 0;
            gCounting = true;
            EXPECT_EQ(nradShadeGBuffer(asset.get(), &g, scratch.data(), scratch.size()), NRAD_OK);
            gCounting = false;
            news = gNews;
        });
        gbuffer.join();
        nradSetAllocator(nullptr, nullptr, nullptr);
        EXPECT_EQ(news, 0u);
        EXPECT_EQ(untouched.allocations.load(), 0u);
    }
}

}  // namespace
}  // namespace nrad
