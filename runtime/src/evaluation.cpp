// Evaluation of a batch, tile by tile: the scratch a tile works in (the caller's, or the thread's through the
// allocator hook), and a tile's points through the kernels' block driver and the grouped pass.
#include "evaluation.h"

#include <algorithm>
#include <atomic>
#include <cmath>
#include <cstdlib>
#include <new>

#include "asset.h"
#include "kernel_dispatch.h"
#include "testing.h"

namespace nrad::rt {
namespace {

// Up to this many entries are ordered by insertion sort; beyond, by a counting sort over the networks when
// they are no more than the entries, else by sorting (network, entry) keys.
constexpr size_t kSmallBatchEntries = 64;

// Network of an occupied voxel, or -1.
int32_t networkOf(const NradAsset_& a, int64_t voxel) {
    if (!a.denseLookup.empty()) return a.denseLookup[size_t(voxel)];
    auto it = std::lower_bound(a.asset.voxels.begin(), a.asset.voxels.end(), uint32_t(voxel),
                               [](const format::VoxelEntry& e, uint32_t v) { return e.index < v; });
    return it != a.asset.voxels.end() && it->index == uint32_t(voxel) ? int32_t(it - a.asset.voxels.begin()) : -1;
}

// The networks that shade p, their weights and p's position in each voxel (nrad/eval.h supports() and
// keepOccupied()); 0 with a flag when there is none.
int locate(const NradAsset_& a, const float p[3], eval::Support s[eval::kMaxSupports], uint8_t& flag) {
    int count = a.partition.supports(p, s);
    if (count == 0) {
        flag = NRAD_POINT_OUTSIDE_GRID;
        return 0;
    }
    count = eval::keepOccupied(s, count, [&](int64_t voxel) { return networkOf(a, voxel) >= 0; });
    flag = count > 0 ? NRAD_POINT_OK : NRAD_POINT_EMPTY_VOXEL;
    return count;
}

bool finite3(const float v[3]) { return std::isfinite(v[0]) && std::isfinite(v[1]) && std::isfinite(v[2]); }

// ----- the allocator hook ---------------------------------------------------------------------------------------

void* defaultAllocate(size_t bytes, void*) { return std::malloc(bytes); }
void defaultFree(void* p, void*) { std::free(p); }
std::atomic<NradAllocateFunction> gAllocate{defaultAllocate};
std::atomic<NradFreeFunction> gFree{defaultFree};
std::atomic<void*> gAllocatorUser{nullptr};

// The calling thread's scratch, allocated through the hook on its first evaluation without caller scratch
// and released when the thread ends (through the hook it was allocated with).
struct ThreadScratch {
    void* memory = nullptr;
    NradFreeFunction release = nullptr;
    void* user = nullptr;
    ~ThreadScratch() {
        if (memory) release(memory, user);
    }
    void* get() {
        if (!memory) {
            user = gAllocatorUser.load();
            release = gFree.load();
            memory = gAllocate.load()(kScratchBytes + kGBufferScratchBytes, user);
            if (!memory) throw std::bad_alloc();
        }
        return memory;
    }
};

// ----- evaluation of one tile -------------------------------------------------------------------------------------

// Locates point i one at a time (the reference path): its supports join the deferred entries; a point
// without any gets zero radiance and its flag.
void locateOne(const NradAsset_& a, const BatchIo& v, size_t i, Scratch& s) {
    size_t at = i * v.stride;
    float p[3] = {v.p[0][at], v.p[1][at], v.p[2][at]};
    float n[3] = {v.n[0][at], v.n[1][at], v.n[2][at]};
    float d[3] = {v.d[0][at], v.d[1][at], v.d[2][at]};
    uint8_t flag = NRAD_POINT_OK;
    eval::Support sup[eval::kMaxSupports];
    int count = 0;
    if (!finite3(p) || !finite3(n) || !finite3(d))
        flag = NRAD_POINT_INVALID_INPUT;
    else
        count = locate(a, p, sup, flag);
    if (v.flags) v.flags[i] = flag;
    if (count == 0) {
        v.out[0][at] = v.out[1][at] = v.out[2][at] = 0.0f;
        return;
    }
    for (int k = 0; k < count; ++k) {
        const size_t e = s.entries++;
        s.index[e] = uint32_t(i);
        s.network[e] = networkOf(a, sup[k].voxel);
        s.weight[e] = sup[k].weight;
        for (int c = 0; c < 3; ++c) s.local[3 * e + size_t(c)] = sup[k].local[c];
    }
}

}  // namespace

Scratch carveScratch(void* memory) {
    const auto base = reinterpret_cast<uintptr_t>(memory);
    auto at = (base + 63) & ~uintptr_t(63);
    auto take = [&](size_t bytes) {
        void* p = reinterpret_cast<void*>(at);
        at += bytes;
        return p;
    };
    Scratch s;
    s.keys = static_cast<uint64_t*>(take(kTileEntries * 8));  // 8-byte aligned first
    s.blocks = static_cast<uint32_t*>(take(kTilePoints * 4));
    s.points = static_cast<uint32_t*>(take(kTilePoints * 4));
    s.index = static_cast<uint32_t*>(take(kTileEntries * 4));
    s.network = static_cast<int32_t*>(take(kTileEntries * 4));
    s.weight = static_cast<float*>(take(kTileEntries * 4));
    s.order = static_cast<uint32_t*>(take(kTileEntries * 4));
    s.local = static_cast<float*>(take(kTileEntries * 12));
    s.start = static_cast<uint32_t*>(take((kTileEntries + 1) * 4));
    s.entries = 0;
    NRAD_CHECK(at - base <= kScratchBytes);  // the arrays fit the block nradScratchBytes asks callers for
    return s;
}

void* threadScratch() {
    thread_local ThreadScratch own;
    return own.get();
}

void setScratchAllocator(NradAllocateFunction allocate, NradFreeFunction release, void* user) {
    const bool both = allocate && release;
    gAllocate.store(both ? allocate : defaultAllocate);
    gFree.store(both ? release : defaultFree);
    gAllocatorUser.store(both ? user : nullptr);
}

BlockDriver blockDriverOf(const NradAsset_& a, int& width) {
    width = 0;
    const bool tree = !a.partition.tree.empty();
    if (a.denseLookup.empty() || (tree && a.partition.starts.empty())) return nullptr;
    const KernelEntry& k = kernelEntry(kernelOf(a));
    if (k.evalBlocks) width = k.blockWidth;
    return k.evalBlocks;
}

// At most kTilePoints points.
void evaluateTile(const NradAsset_& a, size_t count, const BatchIo& v, Scratch& s) {
    const size_t nets = a.asset.voxels.size();
    Deferred def{s.blocks, 0, s.points, 0, s.index, s.network, s.local, 0};
    const ChunkKernel kernel = kernelEntry(kernelOf(a)).evalChunk;
    const format::Topology& t = a.asset.topology;
    const bool exponential = t.outputTransform == format::OutputTransform::Exponential;
    const NetworkView first{a.asset.weights.data(), uint32_t(t.hiddenWidths.size()), t.hiddenWidths.data(),
                                a.scales.empty() ? 1.0f : a.scales[0], exponential};

    // 1. Whole vectors of points through the SIMD block driver: a vector of points in one cell (the common
    //    case for coherent batches) is located and evaluated in registers there; the others are located there
    //    point by point where that is exact (one support), the rest left to step 2.
    int width = 0;
    BlockDriver driver = blockDriverOf(a, width);
    size_t blocks = driver ? count / size_t(width) : 0;
    if (blocks > 0) {
        BlockContext ctx{};
        const format::Grid& g = a.asset.grid;
        for (int k = 0; k < 3; ++k) {
            ctx.grid.lower[k] = g.lower[k];
            ctx.grid.upper[k] = g.upper[k];
            ctx.grid.factor[k] = a.partition.factor[k];
            ctx.grid.dims[k] = g.dims[k];
        }
        ctx.grid.band = a.partition.band;
        ctx.grid.dense = a.denseLookup.data();
        if (!a.partition.tree.empty()) {
            const eval::TreeView view = a.partition.view();
            ctx.tree.nodes = a.treeNodes.data();
            ctx.tree.splits = a.treeSplits.data();
            ctx.tree.starts = a.treeStarts.data();
            for (int k = 0; k < 3; ++k) {
                ctx.tree.startDims[k] = view.startDims[k];
                ctx.tree.startScale[k] = view.startScale[k];
            }
            ctx.tree.leaves = a.treeLeaves.data();
            if (!a.rectLeaves.empty()) {
                ctx.tree.rectAxis = a.rectAxis.data();
                ctx.tree.rectLeaves = a.rectLeaves.data();
                for (int k = 0; k < 3; ++k) ctx.tree.rectOffset[k] = a.rectOffset[k];
            }
        }
        ctx.networks = first;
        ctx.paramsPerNetwork = a.paramsPerNetwork;
        ctx.scales = a.scales.data();
        ctx.io = v;
        driver(ctx, blocks, def);
        testing::countBlocks(def);
    }
    // 2. The rest one point at a time: the points the driver left (in a band it could not blend, in an empty
    //    cell), the blocks with an invalid or outside point, and the tail.
    for (size_t e = 0; e < def.count; ++e) s.weight[e] = 1.0f;
    s.entries = def.count;
    for (size_t k = 0; k < def.pointCount; ++k) locateOne(a, v, def.points[k], s);
    for (size_t b = 0; b < def.blockCount; ++b)
        for (size_t i = size_t(def.blocks[b]) * size_t(width), end = i + size_t(width); i < end; ++i) locateOne(a, v, i, s);
    for (size_t i = blocks * size_t(width); i < count; ++i) locateOne(a, v, i, s);
    const size_t entries = s.entries;
    if (entries == 0) return;

    // 3. Order the deferred entries by network, stably, so every chunk runs one network and each point's
    //    supports are summed in network order, which is their voxel order (eval.h). The cost never depends on
    //    the number of networks beyond the entries (a single point costs the same whatever the asset).
    if (entries <= kSmallBatchEntries) {
        for (size_t e = 0; e < entries; ++e) s.order[e] = uint32_t(e);
        for (size_t e = 1; e < entries; ++e)  // insertion sort: stable, and entries are few
            for (size_t j = e; j > 0 && s.network[s.order[j - 1]] > s.network[s.order[j]]; --j) std::swap(s.order[j - 1], s.order[j]);
    } else if (nets <= entries) {
        std::fill(s.start, s.start + nets + 1, 0u);
        for (size_t e = 0; e < entries; ++e) ++s.start[size_t(s.network[e]) + 1];
        for (size_t k = 0; k < nets; ++k) s.start[k + 1] += s.start[k];
        for (size_t e = 0; e < entries; ++e) s.order[s.start[size_t(s.network[e])]++] = uint32_t(e);
    } else {
        for (size_t e = 0; e < entries; ++e) s.keys[e] = uint64_t(uint32_t(s.network[e])) << 32 | e;  // (network, entry): stable
        std::sort(s.keys, s.keys + entries);
        for (size_t e = 0; e < entries; ++e) s.order[e] = uint32_t(s.keys[e]);
    }
    // 4. Run each network's entries in chunks: gather SoA inputs, evaluate (output transform included),
    //    accumulate the weighted radiance into the zeroed outputs.
    for (size_t e = 0; e < entries; ++e) {
        const size_t at = size_t(s.index[e]) * v.stride;
        v.out[0][at] = v.out[1][at] = v.out[2][at] = 0.0f;
    }
    alignas(64) float x[kInputs * kChunk];
    alignas(64) float y[kOutputs * kChunk];
    for (size_t runStart = 0; runStart < entries;) {
        const int32_t k = s.network[s.order[runStart]];
        size_t runEnd = runStart + 1;
        while (runEnd < entries && s.network[s.order[runEnd]] == k) ++runEnd;
        NetworkView net = first;
        net.params += size_t(k) * a.paramsPerNetwork;
        net.scale = a.scales[size_t(k)];
        for (size_t g = runStart; g < runEnd; g += kChunk) {
            const uint32_t n = uint32_t(std::min<size_t>(kChunk, runEnd - g));
            for (uint32_t j = 0; j < n; ++j) {
                size_t e = s.order[g + j], at = size_t(s.index[e]) * v.stride;
                for (int c = 0; c < 3; ++c) {
                    x[(0 + c) * kChunk + j] = s.local[e * 3 + size_t(c)];
                    x[(3 + c) * kChunk + j] = v.n[c][at];
                    x[(6 + c) * kChunk + j] = v.d[c][at];
                }
            }
            const uint32_t padded = std::min<uint32_t>(kChunk, (n + 15) / 16 * 16);  // whole vectors of any width
            for (int r = 0; r < kInputs; ++r) std::fill(x + r * kChunk + n, x + r * kChunk + padded, 0.0f);
            kernel(net, x, y, int(n));
            for (uint32_t j = 0; j < n; ++j) {
                const size_t e = s.order[g + j], at = size_t(s.index[e]) * v.stride;
                const float w = s.weight[e];
                for (int c = 0; c < 3; ++c) v.out[c][at] += w * y[c * kChunk + int(j)];
            }
        }
        runStart = runEnd;
    }
}

// A batch, tile by tile, in `scratch` (kScratchBytes), or the calling thread's scratch when null.
NradStatus evaluateBatch(const NradAsset_& a, size_t count, const BatchIo& v, void* scratch) {
    Scratch s = carveScratch(scratch ? scratch : threadScratch());
    for (size_t first = 0; first < count; first += kTilePoints) {
        BatchIo part = v;
        for (int c = 0; c < 3; ++c) {
            part.p[c] += first * v.stride;
            part.n[c] += first * v.stride;
            part.d[c] += first * v.stride;
            part.out[c] += first * v.stride;
        }
        if (part.flags) part.flags += first;
        evaluateTile(a, std::min(kTilePoints, count - first), part, s);
    }
    return NRAD_OK;
}

}  // namespace nrad::rt
