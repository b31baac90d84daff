// libnrad: loading (through the format's validating decoder), queries, and batched evaluation grouped by
// voxel with run-time kernel dispatch. Every entry point catches everything: nothing crosses the C API.
#include <algorithm>
#include <atomic>
#include <cmath>
#include <cstddef>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <limits>
#include <new>
#include <string>
#include <vector>

#if (defined(__x86_64__) || defined(_M_X64)) && defined(__GNUC__)
#include <cpuid.h>
#endif

#include <nrad/eval.h>
#include <nrad/format.h>
#include <nrad/nrad.h>

#include "kernels.h"

using namespace nrad;

// NradAssetInfo.contentFlags hands the header's flags through: the C API's names for the same bits.
static_assert(NRAD_CONTENT_SCATTERED_RADIANCE == format::kFlagScatteredRadiance, "content flag bits");
static_assert(NRAD_CONTENT_DEMODULATED == format::kFlagDemodulated, "content flag bits");
static_assert(NRAD_CONTENT_BLENDED == format::kFlagBlended, "content flag bits");
static_assert(NRAD_CONTENT_TREE == format::kFlagTree, "content flag bits");
static_assert(rt::kContentScattered == format::kFlagScatteredRadiance && rt::kContentDemodulated == format::kFlagDemodulated,
              "content flag bits");
static_assert(sizeof(NradSurface) == 9 * sizeof(float), "rt::GBufferIo reads surfaces as nine floats");

struct NradAsset_ {
    format::Asset asset;  // decoded; weights already in fp32
    uint64_t fileBytes = 0;
    std::string metadataCopy;  // NRAD_LOAD_COPY
    const char* metadata = nullptr;  // points into metadataCopy or, for NRAD_LOAD_BORROW, the caller's buffer
    size_t metadataLength = 0;
    uint32_t paramsPerNetwork = 0;
    std::vector<int32_t> denseLookup;  // cell -> network, -1 = empty; used when the grid is small enough
    eval::Partition partition;  // how a point finds its cells (the grid, or the kd-tree's leaves), its band
    std::vector<float> treeLeaves;  // kd-tree assets: rt::LocateTree::leaves (treeLeafBoxes)
    std::vector<int32_t> treeNodes, treeStarts;  // kd-tree assets: rt::LocateTree::nodes and starts (tagTree)
    std::vector<float> treeSplits;  // and rt::LocateTree::splits
    std::vector<int32_t> rectAxis, rectLeaves;  // small kd-trees: rt::LocateTree's rectilinear table (rectilinearTable)
    uint32_t rectOffset[3] = {0, 0, 0};
    std::vector<float> scales;  // per network: the voxel's output scale
    std::atomic<int> kernel{NRAD_KERNEL_AUTO};  // nradSetAssetKernel; AUTO: the process-wide choice
};

namespace {

// ----- kernels and dispatch ----------------------------------------------------------------------------

bool cpuHas(NradKernel k) {
#if (defined(__x86_64__) || defined(_M_X64)) && defined(__GNUC__)
    __builtin_cpu_init();
    if (k == NRAD_KERNEL_AVX2) return __builtin_cpu_supports("avx2") && __builtin_cpu_supports("fma");
    if (k == NRAD_KERNEL_AVX512) return __builtin_cpu_supports("avx512f");
#endif
#if defined(__aarch64__)
    if (k == NRAD_KERNEL_NEON) return true;
#endif
    return k == NRAD_KERNEL_SCALAR;
}

NradKernel bestKernel() {
    if (cpuHas(NRAD_KERNEL_AVX512)) return NRAD_KERNEL_AVX512;
    if (cpuHas(NRAD_KERNEL_AVX2)) return NRAD_KERNEL_AVX2;
    if (cpuHas(NRAD_KERNEL_NEON)) return NRAD_KERNEL_NEON;
    return NRAD_KERNEL_SCALAR;
}

std::atomic<int> gKernel{NRAD_KERNEL_AUTO};
std::atomic<uint64_t> gBlendedBlocks{0};
std::atomic<uint64_t> gGBufferBlocks{0};
std::atomic<uint64_t> gTreeBlocks{0};
std::atomic<size_t> gMaxRectCells{rt::LocateTree::kMaxRectCells};

NradKernel activeKernel() {
    int k = gKernel.load(std::memory_order_relaxed);
    if (k == NRAD_KERNEL_AUTO) {
        k = bestKernel();
        gKernel.store(k, std::memory_order_relaxed);
    }
    return NradKernel(k);
}

rt::ChunkKernel kernelFunction(NradKernel k) {
#if defined(__x86_64__) || defined(_M_X64)
    if (k == NRAD_KERNEL_AVX512) return rt::evalChunkAvx512;
    if (k == NRAD_KERNEL_AVX2) return rt::evalChunkAvx2;
#endif
#if defined(__aarch64__)
    if (k == NRAD_KERNEL_NEON) return rt::evalChunkNeon;
#endif
    (void)k;
    return rt::evalChunkScalar;
}

// The asset's own kernel (nradSetAssetKernel), else the process-wide one.
NradKernel kernelOf(const NradAsset_& a) {
    const int k = a.kernel.load(std::memory_order_relaxed);
    return k == NRAD_KERNEL_AUTO ? activeKernel() : NradKernel(k);
}

// ----- loading -------------------------------------------------------------------------------------------

NradStatus statusOf(format::DecodeStatus s) {
    switch (s) {
        case format::DecodeStatus::Ok: return NRAD_OK;
        case format::DecodeStatus::Truncated: return NRAD_ERROR_TRUNCATED;
        case format::DecodeStatus::BadMagic: return NRAD_ERROR_NOT_AN_ASSET;
        case format::DecodeStatus::UnsupportedVersion: return NRAD_ERROR_UNSUPPORTED_VERSION;
        case format::DecodeStatus::BadHeader:
        case format::DecodeStatus::HeaderCrcMismatch:
        case format::DecodeStatus::BadSectionTable:
        case format::DecodeStatus::SectionCrcMismatch:
        case format::DecodeStatus::TrailingBytes: return NRAD_ERROR_CORRUPT;
        default: return NRAD_ERROR_INVALID_CONTENT;
    }
}

void writeMessage(char* message, size_t size, const std::string& text) {
    if (!message || size == 0) return;
    size_t n = std::min(size - 1, text.size());
    std::memcpy(message, text.data(), n);
    message[n] = '\0';
}

// rt::LocateTree::leaves of a kd-tree partition: per leaf, the open box of lattice coordinates whose points
// have that leaf alone with weight 1 (eval::treeSupports), and the leaf's box as floats. Walking down from the
// whole lattice, a node's lower child keeps t < split - width and its upper child t > split + width (outside
// the node's blending band, on its side); each bound moves inwards by a margin of 1e-3 lattice voxels (more
// on lattices past 256 voxels, 30 float ulps at least) so that no rounding of t - split puts a point of the
// box on the other side of the descent's test. The grid's own faces need no margin.
std::vector<float> treeLeafBoxes(const eval::Partition& part) {
    const std::vector<format::TreeNode>& nodes = part.tree;
    std::vector<float> out(size_t(part.cells) * 12, 0.0f);
    uint32_t maxDim = 1;
    for (int k = 0; k < 3; ++k) maxDim = std::max(maxDim, part.grid.dims[k]);
    const float margin = 1e-3f * std::max(1.0f, float(maxDim) / 256.0f);
    struct Item {
        uint32_t node;
        float lo[3], hi[3];
    };
    std::vector<Item> stack{{0, {0.0f, 0.0f, 0.0f}, {float(part.grid.dims[0]), float(part.grid.dims[1]), float(part.grid.dims[2])}}};
    while (!stack.empty()) {
        const Item it = stack.back();
        stack.pop_back();
        const format::TreeNode& n = nodes[it.node];
        if (n.axis == format::kTreeLeaf) {
            float* o = &out[size_t(n.child) * 12];
            const format::TreeBox& b = part.boxes[n.child];
            for (int k = 0; k < 3; ++k) {
                o[k] = it.lo[k];
                o[3 + k] = it.hi[k];
                o[6 + k] = float(b.lo[k]);
                o[9 + k] = float(b.hi[k] - b.lo[k]);
            }
            continue;
        }
        const float split = float(n.split), w = part.widths[it.node];
        Item lower = it, upper = it;
        lower.node = n.child;
        lower.hi[n.axis] = std::min(lower.hi[n.axis], split - w - margin);
        upper.node = n.child + 1;
        upper.lo[n.axis] = std::max(upper.lo[n.axis], split + w + margin);
        stack.push_back(lower);
        stack.push_back(upper);
    }
    return out;
}

// rt::LocateTree::nodes, splits and starts of a kd-tree partition: every node reference tagged (an inner
// node's index, or -1 - leaf).
void tagTree(const eval::Partition& part, std::vector<int32_t>& nodes, std::vector<float>& splits, std::vector<int32_t>& starts) {
    const std::vector<format::TreeNode>& tree = part.tree;
    auto tag = [&](uint32_t n) {
        return tree[n].axis == format::kTreeLeaf ? -1 - int32_t(tree[n].child) : int32_t(n);
    };
    nodes.assign(3 * tree.size(), 0);
    splits.assign(tree.size(), 0.0f);
    for (size_t i = 0; i < tree.size(); ++i) {
        if (tree[i].axis == format::kTreeLeaf) continue;
        nodes[3 * i] = int32_t(tree[i].axis);
        nodes[3 * i + 1] = tag(tree[i].child);
        nodes[3 * i + 2] = tag(tree[i].child + 1);
        splits[i] = float(tree[i].split);
    }
    starts.resize(part.starts.size());
    for (size_t c = 0; c < starts.size(); ++c) starts[c] = tag(part.starts[c]);
}

// rt::LocateTree's rectilinear table of a kd-tree partition (every distinct split of each axis cuts the
// lattice; each cell of the product lies in one leaf, the leaf of its lowest voxel's corner: eval::treeLeafAt),
// both left empty past kMaxRectCells cells (setMaxRectCells).
void rectilinearTable(const eval::Partition& part, std::vector<int32_t>& axis, std::vector<int32_t>& leaves, uint32_t offset[3]) {
    axis.clear();
    leaves.clear();
    std::vector<std::vector<uint32_t>> cuts(3);  // per axis: the lower voxel of each interval
    for (int k = 0; k < 3; ++k) cuts[k].push_back(0);
    for (const format::TreeNode& n : part.tree)
        if (n.axis != format::kTreeLeaf) cuts[n.axis].push_back(n.split);
    size_t cells = 1;
    for (int k = 0; k < 3; ++k) {
        std::sort(cuts[k].begin(), cuts[k].end());
        cuts[k].erase(std::unique(cuts[k].begin(), cuts[k].end()), cuts[k].end());
        cells *= cuts[k].size();
        if (cells > gMaxRectCells.load(std::memory_order_relaxed)) return;
    }
    const uint32_t* dims = part.grid.dims;
    int32_t stride = 1;
    for (int k = 0; k < 3; ++k) {
        offset[k] = uint32_t(axis.size());
        for (uint32_t v = 0, interval = 0; v < dims[k]; ++v) {
            while (interval + 1 < cuts[k].size() && cuts[k][interval + 1] <= v) ++interval;
            axis.push_back(int32_t(interval) * stride);
        }
        stride *= int32_t(cuts[k].size());
    }
    leaves.resize(cells);
    for (size_t z = 0; z < cuts[2].size(); ++z)
        for (size_t y = 0; y < cuts[1].size(); ++y)
            for (size_t x = 0; x < cuts[0].size(); ++x) {
                const float t[3] = {float(cuts[0][x]), float(cuts[1][y]), float(cuts[2][z])};
                format::TreeBox box;
                leaves[(z * cuts[1].size() + y) * cuts[0].size() + x] = int32_t(eval::treeLeafAt(part.tree.data(), t, box));
            }
}

NradStatus load(const void* data, size_t size, uint32_t flags, NradAsset* out, char* message, size_t messageSize) {
    if (!out) return NRAD_ERROR_INVALID_ARGUMENT;
    *out = nullptr;
    if ((!data && size > 0) || flags > NRAD_LOAD_BORROW) {
        writeMessage(message, messageSize, "invalid argument");
        return NRAD_ERROR_INVALID_ARGUMENT;
    }
    auto* a = new NradAsset_();
    format::DecodeStatus st = format::decode(static_cast<const uint8_t*>(data), size, a->asset);
    if (st != format::DecodeStatus::Ok) {
        delete a;
        writeMessage(message, messageSize, format::decodeStatusString(st));
        return statusOf(st);
    }
    a->fileBytes = size;
    a->paramsPerNetwork = uint32_t(a->asset.topology.parameterCount());
    if (flags == NRAD_LOAD_COPY) {
        a->metadataCopy.swap(a->asset.metadata);
        a->metadata = a->metadataCopy.data();
        a->metadataLength = a->metadataCopy.size();
    } else if (!a->asset.metadata.empty()) {
        // Find the metadata in the caller's buffer: it is the META section's bytes.
        const std::string& m = a->asset.metadata;
        const uint8_t* bytes = static_cast<const uint8_t*>(data);
        a->metadataLength = m.size();
        a->metadata = reinterpret_cast<const char*>(bytes + size - m.size());  // META is written last
        if (std::memcmp(a->metadata, m.data(), m.size()) != 0) {  // not last (a foreign writer): keep a copy
            a->metadataCopy = m;
            a->metadata = a->metadataCopy.data();
        }
        std::string().swap(a->asset.metadata);
    }
    for (const format::VoxelEntry& e : a->asset.voxels) a->scales.push_back(e.scale);
    a->partition = eval::Partition(a->asset);
    std::vector<format::TreeNode>().swap(a->asset.tree);  // the partition holds it
    if (!a->partition.tree.empty()) {
        a->treeLeaves = treeLeafBoxes(a->partition);
        tagTree(a->partition, a->treeNodes, a->treeSplits, a->treeStarts);
        rectilinearTable(a->partition, a->rectAxis, a->rectLeaves, a->rectOffset);  // empty when too large
    }
    // A dense cell -> network table when it is small next to the networks themselves; else binary search.
    uint64_t voxels = a->partition.cells;
    if (voxels <= std::max<uint64_t>(1u << 16, uint64_t(a->asset.voxels.size()) * 64)) {
        a->denseLookup.assign(size_t(voxels), -1);
        for (size_t i = 0; i < a->asset.voxels.size(); ++i) a->denseLookup[a->asset.voxels[i].index] = int32_t(i);
    }
    *out = a;
    writeMessage(message, messageSize, "ok");
    return NRAD_OK;
}

// ----- evaluation ------------------------------------------------------------------------------------------

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

rt::BlockDriver blockDriver(NradKernel k, int& width) {
#if defined(__x86_64__) || defined(_M_X64)
    if (k == NRAD_KERNEL_AVX512) {
        width = rt::kAvx512Width;
        return rt::evalBlocksAvx512;
    }
    if (k == NRAD_KERNEL_AVX2) {
        width = rt::kAvx2Width;
        return rt::evalBlocksAvx2;
    }
#endif
#if defined(__aarch64__)
    if (k == NRAD_KERNEL_NEON) {
        width = rt::kNeonWidth;
        return rt::evalBlocksNeon;
    }
#endif
    (void)k;
    width = 0;
    return nullptr;
}

// The asset's block driver and its width: on a vector kernel, for assets with a dense cell -> network table
// (kd-trees: with their start table too); else null and 0.
rt::BlockDriver blockDriverOf(const NradAsset_& a, int& width) {
    width = 0;
    const bool tree = !a.partition.tree.empty();
    return a.denseLookup.empty() || (tree && a.partition.starts.empty()) ? nullptr : blockDriver(kernelOf(a), width);
}

// ----- scratch: everything evaluation needs besides the caller's arrays --------------------------------------

// Evaluation works on tiles of at most kTilePoints points; a tile's deferred entries (point, network, weight,
// position in the network's cell) number at most kMaxSupports per point. All of it lives in one block of
// memory carved into the arrays below: the caller's (nradGetScratchSize), or a per-thread block allocated
// once through the allocator hook and reused.
constexpr size_t kTilePoints = 1024;
constexpr size_t kTileEntries = kTilePoints * eval::kMaxSupports;
// Up to this many entries are ordered by insertion sort; beyond, by a counting sort over the networks when
// they are no more than the entries, else by sorting (network, entry) keys.
constexpr size_t kSmallBatchEntries = 64;

struct Scratch {
    uint32_t* blocks;  // kTilePoints each: blocks and single points left to the general path
    uint32_t* points;
    uint32_t* index;  // kTileEntries each, then
    int32_t* network;
    float* weight;
    uint32_t* order;
    uint64_t* keys;
    float* local;  // 3 x kTileEntries
    uint32_t* start;  // kTileEntries + 1 (counting sort)
    size_t entries;
};

constexpr size_t kScratchBytes =
    kTilePoints * 8 + kTileEntries * (4 + 4 + 4 + 4 + 8 + 12) + (kTileEntries + 1) * 4 + 64;  // + alignment

// A tile's fp32 copy of the G-buffer: what nradShadeGBuffer converts into before evaluating (after the
// evaluation scratch in the same block).
struct GBufferTile {
    float p[3 * kTilePoints], n[3 * kTilePoints], d[3 * kTilePoints], rgb[3 * kTilePoints];
    float color[4 * kTilePoints];  // the output's channels in fp32
    uint16_t halves[4 * kTilePoints];  // fp16 staging, in and out
    uint8_t done[kTilePoints];  // pixels the block driver wrote itself (rt::GBufferIo)
};
constexpr size_t kGBufferScratchBytes = sizeof(GBufferTile) + 64;

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

// The calling thread's scratch block (one per thread, shared by every entry point).
void* threadScratch() {
    thread_local ThreadScratch own;
    return own.get();
}

// ----- evaluation of one tile -------------------------------------------------------------------------------------

// Locates point i one at a time (the reference path): its supports join the deferred entries; a point
// without any gets zero radiance and its flag.
void locateOne(const NradAsset_& a, const rt::BatchIo& v, size_t i, Scratch& s) {
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

// At most kTilePoints points.
void evaluateTile(const NradAsset_& a, size_t count, const rt::BatchIo& v, Scratch& s) {
    const size_t nets = a.asset.voxels.size();
    rt::Deferred def{s.blocks, 0, s.points, 0, s.index, s.network, s.local, 0, 0, 0, 0};
    const NradKernel kind = kernelOf(a);
    const rt::ChunkKernel kernel = kernelFunction(kind);
    const format::Topology& t = a.asset.topology;
    const bool exponential = t.outputTransform == format::OutputTransform::Exponential;
    const rt::NetworkView first{a.asset.weights.data(), uint32_t(t.hiddenWidths.size()), t.hiddenWidths.data(),
                                a.scales.empty() ? 1.0f : a.scales[0], exponential};

    // 1. Whole vectors of points through the SIMD block driver: a vector of points in one cell (the common
    //    case for coherent batches) is located and evaluated in registers there; the others are located there
    //    point by point where that is exact (one support), the rest left to step 2.
    int width = 0;
    rt::BlockDriver driver = blockDriverOf(a, width);
    size_t blocks = driver ? count / size_t(width) : 0;
    if (blocks > 0) {
        rt::BlockContext ctx{};
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
        if (def.blendedBlocks) gBlendedBlocks.fetch_add(def.blendedBlocks, std::memory_order_relaxed);
        if (def.gbufferBlocks) gGBufferBlocks.fetch_add(def.gbufferBlocks, std::memory_order_relaxed);
        if (def.treeBlocks) gTreeBlocks.fetch_add(def.treeBlocks, std::memory_order_relaxed);
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
    alignas(64) float x[rt::kInputs * rt::kChunk];
    alignas(64) float y[rt::kOutputs * rt::kChunk];
    for (size_t runStart = 0; runStart < entries;) {
        const int32_t k = s.network[s.order[runStart]];
        size_t runEnd = runStart + 1;
        while (runEnd < entries && s.network[s.order[runEnd]] == k) ++runEnd;
        rt::NetworkView net = first;
        net.params += size_t(k) * a.paramsPerNetwork;
        net.scale = a.scales[size_t(k)];
        for (size_t g = runStart; g < runEnd; g += rt::kChunk) {
            const uint32_t n = uint32_t(std::min<size_t>(rt::kChunk, runEnd - g));
            for (uint32_t j = 0; j < n; ++j) {
                size_t e = s.order[g + j], at = size_t(s.index[e]) * v.stride;
                for (int c = 0; c < 3; ++c) {
                    x[(0 + c) * rt::kChunk + j] = s.local[e * 3 + size_t(c)];
                    x[(3 + c) * rt::kChunk + j] = v.n[c][at];
                    x[(6 + c) * rt::kChunk + j] = v.d[c][at];
                }
            }
            const uint32_t padded = std::min<uint32_t>(rt::kChunk, (n + 15) / 16 * 16);  // whole vectors of any width
            for (int r = 0; r < rt::kInputs; ++r) std::fill(x + r * rt::kChunk + n, x + r * rt::kChunk + padded, 0.0f);
            kernel(net, x, y, int(n));
            for (uint32_t j = 0; j < n; ++j) {
                const size_t e = s.order[g + j], at = size_t(s.index[e]) * v.stride;
                const float w = s.weight[e];
                for (int c = 0; c < 3; ++c) v.out[c][at] += w * y[c * rt::kChunk + int(j)];
            }
        }
        runStart = runEnd;
    }
}

// A batch, tile by tile, in `scratch` (kScratchBytes), or the calling thread's scratch when null.
NradStatus evaluateBatch(const NradAsset_& a, size_t count, const rt::BatchIo& v, void* scratch = nullptr) {
    Scratch s = carveScratch(scratch ? scratch : threadScratch());
    for (size_t first = 0; first < count; first += kTilePoints) {
        rt::BatchIo part = v;
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

// ----- the GPU buffer (nrad.h, docs/runtime.md "GPU buffers") -------------------------------------------------

// Word offsets of the header's fields; runtime/shaders/nrad.glsl reads the same ones.
namespace gpu {
constexpr uint32_t kMagic = 0x5047524Eu;  // "NRGP"
constexpr uint32_t kHeaderWords = 64;
enum Word : uint32_t {
    kWordMagic = 0, kWordVersion = 1, kWordContentFlags = 2, kWordOutputTransform = 3, kWordLower = 4, kWordUpper = 7,
    kWordDims = 10, kWordFactor = 13, kWordBand = 16, kWordHiddenLayers = 17, kWordHiddenWidths = 18,
    kWordParamsPerNetwork = 26, kWordNetworks = 27, kWordCells = 28, kWordTreeNodes = 29, kWordCellTable = 30,
    kWordScales = 31, kWordNodes = 32, kWordWidths = 33, kWordBoxes = 34, kWordWeights = 35, kWordTotal = 36
};

struct Layout {
    uint64_t cellTable, scales, nodes, widths, boxes, weights, total;  // in words
};

NradStatus layoutOf(const NradAsset_& a, Layout& l) {
    const format::Topology& t = a.asset.topology;
    for (uint32_t w : t.hiddenWidths)
        if (w > NRAD_GPU_MAX_HIDDEN_WIDTH) return NRAD_ERROR_UNSUPPORTED_GPU_LAYOUT;
    if (t.hiddenWidths.size() > NRAD_MAX_HIDDEN_LAYERS || a.partition.cells > NRAD_GPU_MAX_CELLS)
        return NRAD_ERROR_UNSUPPORTED_GPU_LAYOUT;
    const uint64_t nodes = a.partition.tree.size(), leaves = a.partition.tree.empty() ? 0 : a.partition.cells;
    const uint64_t halves = uint64_t(a.asset.voxels.size()) * a.paramsPerNetwork;
    l.cellTable = kHeaderWords;
    l.scales = l.cellTable + a.partition.cells;
    l.nodes = l.scales + a.asset.voxels.size();
    l.widths = l.nodes + 2 * nodes;
    l.boxes = l.widths + nodes;
    l.weights = l.boxes + 6 * leaves;
    l.total = l.weights + (halves + 1) / 2;
    return l.total * 4 <= UINT32_MAX ? NRAD_OK : NRAD_ERROR_UNSUPPORTED_GPU_LAYOUT;  // offsets are 32-bit words
}

uint32_t bitsOf(float f) {
    uint32_t u;
    std::memcpy(&u, &f, 4);
    return u;
}

void pack(const NradAsset_& a, const Layout& l, uint32_t* w) {
    std::memset(w, 0, size_t(l.total) * 4);
    const format::Grid& g = a.asset.grid;
    const format::Topology& t = a.asset.topology;
    w[kWordMagic] = kMagic;
    w[kWordVersion] = NRAD_GPU_LAYOUT_VERSION;
    w[kWordContentFlags] = a.asset.header.flags & format::kKnownFlags;
    w[kWordOutputTransform] = uint32_t(t.outputTransform);
    for (int k = 0; k < 3; ++k) {
        w[kWordLower + k] = bitsOf(g.lower[k]);
        w[kWordUpper + k] = bitsOf(g.upper[k]);
        w[kWordDims + k] = g.dims[k];
        w[kWordFactor + k] = bitsOf(a.partition.factor[k]);
    }
    w[kWordBand] = bitsOf(a.partition.band);
    w[kWordHiddenLayers] = uint32_t(t.hiddenWidths.size());
    for (size_t i = 0; i < t.hiddenWidths.size(); ++i) w[kWordHiddenWidths + i] = t.hiddenWidths[i];
    w[kWordParamsPerNetwork] = a.paramsPerNetwork;
    w[kWordNetworks] = uint32_t(a.asset.voxels.size());
    w[kWordCells] = uint32_t(a.partition.cells);
    w[kWordTreeNodes] = uint32_t(a.partition.tree.size());
    w[kWordCellTable] = uint32_t(l.cellTable);
    w[kWordScales] = uint32_t(l.scales);
    w[kWordNodes] = uint32_t(l.nodes);
    w[kWordWidths] = uint32_t(l.widths);
    w[kWordBoxes] = uint32_t(l.boxes);
    w[kWordWeights] = uint32_t(l.weights);
    w[kWordTotal] = uint32_t(l.total);
    for (uint64_t c = 0; c < a.partition.cells; ++c) w[l.cellTable + c] = UINT32_MAX;  // -1: no network
    for (size_t i = 0; i < a.asset.voxels.size(); ++i) {
        w[l.cellTable + a.asset.voxels[i].index] = uint32_t(i);
        w[l.scales + i] = bitsOf(a.scales[i]);
    }
    const std::vector<format::TreeNode>& nodes = a.partition.tree;
    for (size_t i = 0; i < nodes.size(); ++i) {
        w[l.nodes + 2 * i] = nodes[i].axis | (nodes[i].split << 2);  // as the file's TREE records
        w[l.nodes + 2 * i + 1] = nodes[i].child;
        w[l.widths + i] = bitsOf(a.partition.widths[i]);
    }
    for (size_t i = 0; i < a.partition.boxes.size(); ++i)
        for (int k = 0; k < 3; ++k) {
            w[l.boxes + 6 * i + size_t(k)] = a.partition.boxes[i].lo[k];
            w[l.boxes + 6 * i + 3 + size_t(k)] = a.partition.boxes[i].hi[k];
        }
    const std::vector<float>& weights = a.asset.weights;
    for (size_t i = 0; i < weights.size(); ++i)
        w[l.weights + i / 2] |= uint32_t(format::floatToHalf(weights[i])) << (16 * (i & 1));
}
}  // namespace gpu

// ----- shading and G-buffers -------------------------------------------------------------------------------------

// The final radiance of one point from what the asset returned there (nradShadeBatch's contract).
void shadeOne(const NradAsset_& a, const NradSurface& in, const float n[3], const float d[3], float rgb[3]) {
    eval::Surface s;
    for (int c = 0; c < 3; ++c) {
        s.baseColor[c] = in.baseColor[c];
        s.emission[c] = std::isfinite(in.emission[c]) ? in.emission[c] : 0.0f;
    }
    s.metallic = in.metallic;
    s.roughness = in.roughness;
    s.specular = in.specular;
    const float cosNV = n[0] * d[0] + n[1] * d[1] + n[2] * d[2];
    float out[3];
    eval::shade(a.asset.header.flags, rgb, s, std::isfinite(cosNV) ? cosNV : 0.0f, out);
    for (int c = 0; c < 3; ++c) rgb[c] = std::isfinite(out[c]) ? out[c] : 0.0f;
}

// v / |v|, or NaN (an invalid input) where v is zero or not finite.
void normalise(float v[3]) {
    const float len2 = v[0] * v[0] + v[1] * v[1] + v[2] * v[2];
    if (len2 > 0.0f && std::isfinite(len2)) {
        const float inv = 1.0f / std::sqrt(len2);
        for (int k = 0; k < 3; ++k) v[k] *= inv;
    } else {
        v[0] = v[1] = v[2] = std::numeric_limits<float>::quiet_NaN();
    }
}

// fp16 conversions: F16C where the CPU has it (and a vector kernel is in use), NEON's with the NEON kernel, else
// the format's scalar ones.
struct HalfConverters {
    rt::HalfToFloat toFloat;
    rt::FloatToHalf toHalf;
};
HalfConverters halfConverters(NradKernel kernel) {
#if (defined(__x86_64__) || defined(_M_X64)) && defined(__GNUC__)
    // CPUID leaf 1, ECX bit 29: F16C (clang's __builtin_cpu_supports does not know the name).
    static const bool f16c = cpuHas(NRAD_KERNEL_AVX2) && [] {
        unsigned eax = 0, ebx = 0, ecx = 0, edx = 0;
        return __get_cpuid(1, &eax, &ebx, &ecx, &edx) && (ecx & (1u << 29)) != 0;
    }();
    if (f16c && kernel != NRAD_KERNEL_SCALAR) return {rt::halfToFloatF16c, rt::floatToHalfF16c};
#endif
#if defined(__aarch64__)
    if (kernel == NRAD_KERNEL_NEON) return {rt::halfToFloatNeon, rt::floatToHalfNeon};
#endif
    return {rt::halfToFloatScalar, rt::floatToHalfScalar};
}

// Points [first, first + n) of an attribute into 3 n floats (`staging`: 3 n halves of room).
void gather(const NradAttribute& at, size_t first, size_t n, float* out, uint16_t* staging, const HalfConverters& conv) {
    const bool half = at.format == NRAD_FORMAT_F16;
    const size_t size = half ? 6 : 12, stride = at.stride ? at.stride : size;
    const uint8_t* src = static_cast<const uint8_t*>(at.data) + first * stride;
    void* dst = half ? static_cast<void*>(staging) : static_cast<void*>(out);
    auto* d = static_cast<uint8_t*>(dst);
    if (stride == size)
        std::memcpy(dst, src, n * size);
    else if (half)  // constant sizes: the copies become plain moves
        for (size_t j = 0; j < n; ++j) std::memcpy(d + j * 6, src + j * stride, 6);
    else
        for (size_t j = 0; j < n; ++j) std::memcpy(d + j * 12, src + j * stride, 12);
    if (half) conv.toFloat(staging, out, 3 * n);
}

// n pixels of `size` bytes from `packed` to `out`, `stride` bytes apart.
template <size_t kSize>
void scatterPixels(const uint8_t* packed, uint8_t* out, size_t stride, size_t n) {
    for (size_t j = 0; j < n; ++j) std::memcpy(out + j * stride, packed + j * kSize, kSize);
}

rt::StridedAttribute stridedOf(const NradAttribute& at, size_t first) {
    const bool half = at.format == NRAD_FORMAT_F16;
    const size_t stride = at.stride ? at.stride : (half ? 6 : 12);
    return {static_cast<const uint8_t*>(at.data) + first * stride, stride, half};
}

// A G-buffer, tile by tile. Where the asset has a block driver, the driver reads each whole vector of texels
// straight from the caller's attributes (rt::GBufferIo), shades and writes its pixels; the rest of a tile (the
// last partial vector, and the points the driver leaves to the other paths, which it converts into the tile's
// fp32 arrays) is gathered, evaluated, shaded and written here. Either way a point gets the same bits.
void shadeGBuffer(const NradAsset_& a, const NradGBuffer& g, void* scratch) {
    Scratch s = carveScratch(scratch);
    auto tileAt = (reinterpret_cast<uintptr_t>(scratch) + kScratchBytes + 63) & ~uintptr_t(63);
    GBufferTile& t = *reinterpret_cast<GBufferTile*>(tileAt);
    const HalfConverters conv = halfConverters(kernelOf(a));
    const bool eye = (g.flags & NRAD_GBUFFER_EYE) != 0, unit = (g.flags & NRAD_GBUFFER_UNIT_VECTORS) != 0;
    const bool half = g.outputFormat == NRAD_FORMAT_F16;
    const size_t channels = g.outputChannels, pixel = channels * (half ? 2 : 4);
    const size_t outStride = g.outputStride ? g.outputStride : pixel;
    const size_t surfaceStride = g.surfaceStride ? g.surfaceStride : sizeof(NradSurface);
    int width = 0;
    const bool fused = blockDriverOf(a, width) != nullptr;
    for (size_t first = 0; first < g.count; first += kTilePoints) {
        const size_t n = std::min(kTilePoints, g.count - first);
        // The points the block driver will not read: all of them without one, else the last partial vector.
        const size_t from = fused ? n / size_t(width) * size_t(width) : 0;
        gather(g.position, first + from, n - from, t.p + 3 * from, t.halves, conv);
        gather(g.normal, first + from, n - from, t.n + 3 * from, t.halves, conv);
        if (!eye) gather(g.direction, first + from, n - from, t.d + 3 * from, t.halves, conv);
        if (eye || !unit)
            for (size_t j = from; j < n; ++j) {
                float* d = t.d + 3 * j;
                if (eye)
                    for (int k = 0; k < 3; ++k) d[k] = g.eye[k] - t.p[3 * j + size_t(k)];
                normalise(d);
                if (!unit) normalise(t.n + 3 * j);
            }
        rt::GBufferIo io{};
        if (fused) {
            io.p = stridedOf(g.position, first);
            io.n = stridedOf(g.normal, first);
            if (!eye) io.d = stridedOf(g.direction, first);
            io.eye = eye;
            for (int k = 0; k < 3; ++k) io.eyePosition[k] = g.eye[k];
            io.normaliseNormals = !unit;
            io.normaliseDirections = eye || !unit;
            // Points whose wide reads (4 bytes past an fp32 point, 2 past an fp16 one) stay inside the attributes:
            // all but the G-buffer's last (its last few with strides under 4 bytes: overlapping attributes).
            auto unsafeTail = [](const rt::StridedAttribute& at) {
                const size_t extra = at.half ? 2 : 4;
                return (extra + at.stride - 1) / at.stride;
            };
            const size_t tail = std::max({unsafeTail(io.p), unsafeTail(io.n), eye ? size_t(0) : unsafeTail(io.d)});
            const size_t safeEnd = g.count > tail ? g.count - tail : 0;
            io.safePoints = safeEnd > first ? std::min(n, safeEnd - first) : 0;
            io.out = static_cast<uint8_t*>(g.output) + first * outStride;
            io.outStride = outStride;
            io.outHalf = half;
            io.channels = int(channels);
            io.done = t.done;
            std::memset(t.done, 0, n);
            if (g.surfaces) {
                io.surfaces = reinterpret_cast<const uint8_t*>(g.surfaces) + first * surfaceStride;
                io.surfaceStride = surfaceStride;
                io.contentFlags = a.asset.header.flags;
            }
        }
        const rt::BatchIo v{{t.p, t.p + 1, t.p + 2}, {t.n, t.n + 1, t.n + 2}, {t.d, t.d + 1, t.d + 2},
                            {t.rgb, t.rgb + 1, t.rgb + 2}, 3, g.pointFlags ? g.pointFlags + first : nullptr,
                            fused ? &io : nullptr};
        evaluateTile(a, n, v, s);
        // The pixels the driver did not write, run by run: the output's channels in fp32, shaded where asked,
        // then converted and stored with the output's stride.
        for (size_t runStart = 0; runStart < n;) {
            if (fused && t.done[runStart]) {  // the driver writes whole vectors
                runStart += size_t(width);
                continue;
            }
            size_t runEnd = runStart + 1;
            while (runEnd < n && !(fused && t.done[runEnd])) ++runEnd;
            const size_t m = runEnd - runStart;
            for (size_t j = runStart; j < runEnd; ++j) {
                float* rgb = t.rgb + 3 * j;
                if (g.surfaces) {
                    NradSurface surface;  // any alignment
                    std::memcpy(&surface, reinterpret_cast<const uint8_t*>(g.surfaces) + (first + j) * surfaceStride, sizeof surface);
                    shadeOne(a, surface, t.n + 3 * j, t.d + 3 * j, rgb);
                }
                float* c = t.color + channels * (j - runStart);
                c[0] = rgb[0];
                c[1] = rgb[1];
                c[2] = rgb[2];
                if (channels == 4) c[3] = 1.0f;
            }
            const void* packed = t.color;
            if (half) {
                conv.toHalf(t.color, t.halves, channels * m);
                packed = t.halves;
            }
            uint8_t* out = static_cast<uint8_t*>(g.output) + (first + runStart) * outStride;
            const auto* bytes = static_cast<const uint8_t*>(packed);
            if (outStride == pixel)
                std::memcpy(out, packed, m * pixel);
            else if (pixel == 6)
                scatterPixels<6>(bytes, out, outStride, m);
            else if (pixel == 8)
                scatterPixels<8>(bytes, out, outStride, m);
            else if (pixel == 12)
                scatterPixels<12>(bytes, out, outStride, m);
            else
                scatterPixels<16>(bytes, out, outStride, m);
            runStart = runEnd;
        }
    }
}

template <typename F>
NradStatus guarded(F&& f) {
    try {
        return f();
    } catch (const std::bad_alloc&) {
        return NRAD_ERROR_OUT_OF_MEMORY;
    } catch (...) {
        return NRAD_ERROR_INTERNAL;
    }
}

}  // namespace

uint64_t nrad::rt::blendedBlocksSoFar() { return gBlendedBlocks.load(std::memory_order_relaxed); }
uint64_t nrad::rt::gbufferBlocksSoFar() { return gGBufferBlocks.load(std::memory_order_relaxed); }
uint64_t nrad::rt::treeBlocksSoFar() { return gTreeBlocks.load(std::memory_order_relaxed); }
void nrad::rt::setMaxRectCells(size_t cells) { gMaxRectCells.store(cells, std::memory_order_relaxed); }

extern "C" {

uint32_t nradGetVersion(void) { return NRAD_VERSION; }

const char* nradStatusString(NradStatus status) {
    switch (status) {
        case NRAD_OK: return "ok";
        case NRAD_ERROR_INVALID_ARGUMENT: return "invalid argument";
        case NRAD_ERROR_OUT_OF_MEMORY: return "out of memory";
        case NRAD_ERROR_IO: return "the file could not be read";
        case NRAD_ERROR_TRUNCATED: return "the asset is truncated";
        case NRAD_ERROR_NOT_AN_ASSET: return "not an .nrad asset";
        case NRAD_ERROR_UNSUPPORTED_VERSION: return "unsupported asset format version";
        case NRAD_ERROR_CORRUPT: return "the asset is damaged (checksum or structure)";
        case NRAD_ERROR_INVALID_CONTENT: return "the asset's content is invalid";
        case NRAD_ERROR_UNSUPPORTED_KERNEL: return "this CPU cannot run the requested kernel";
        case NRAD_ERROR_INTERNAL: return "internal error";
        case NRAD_ERROR_UNSUPPORTED_GPU_LAYOUT: return "the asset exceeds the GPU layout's limits";
    }
    return "unknown status";
}

NradStatus nradLoadFromMemory(const void* data, size_t size, uint32_t flags, NradAsset* asset, char* message,
                              size_t messageSize) {
    return guarded([&] { return load(data, size, flags, asset, message, messageSize); });
}

NradStatus nradLoadFromFile(const char* path, NradAsset* asset, char* message, size_t messageSize) {
    return guarded([&] {
        if (!path || !asset) return NRAD_ERROR_INVALID_ARGUMENT;
        *asset = nullptr;
        std::ifstream f(path, std::ios::binary);
        if (!f) {
            writeMessage(message, messageSize, std::string(path) + ": cannot open file");
            return NRAD_ERROR_IO;
        }
        std::vector<char> bytes((std::istreambuf_iterator<char>(f)), std::istreambuf_iterator<char>());
        if (f.bad()) {
            writeMessage(message, messageSize, std::string(path) + ": read error");
            return NRAD_ERROR_IO;
        }
        NradStatus st = load(bytes.data(), bytes.size(), NRAD_LOAD_COPY, asset, message, messageSize);
        if (st != NRAD_OK && message && messageSize > 0) {
            std::string m = std::string(path) + ": " + message;
            writeMessage(message, messageSize, m);
        }
        return st;
    });
}

void nradReleaseAsset(NradAsset asset) { delete asset; }

NradStatus nradGetAssetInfo(NradAsset a, NradAssetInfo* info) {
    if (!a || !info) return NRAD_ERROR_INVALID_ARGUMENT;
    return guarded([&] {
        NradAssetInfo r;
        std::memset(&r, 0, sizeof r);
        r.formatVersionMajor = a->asset.header.versionMajor;
        r.formatVersionMinor = a->asset.header.versionMinor;
        for (int k = 0; k < 3; ++k) {
            r.gridLower[k] = a->asset.grid.lower[k];
            r.gridUpper[k] = a->asset.grid.upper[k];
            r.gridDims[k] = a->asset.grid.dims[k];
        }
        const format::Topology& t = a->asset.topology;
        r.occupiedVoxels = uint32_t(a->asset.voxels.size());
        r.inputs = t.inputs;
        r.outputs = t.outputs;
        r.hiddenLayers = uint32_t(t.hiddenWidths.size());
        for (size_t l = 0; l < t.hiddenWidths.size() && l < NRAD_MAX_HIDDEN_LAYERS; ++l) r.hiddenWidths[l] = t.hiddenWidths[l];
        r.parametersPerNetwork = a->paramsPerNetwork;
        r.weightEncoding = uint32_t(t.weightEncoding);
        r.outputTransform = uint32_t(t.outputTransform);
        r.contentFlags = a->asset.header.flags & format::kKnownFlags;  // NRAD_CONTENT_* are the header's flags
        r.blendBand = a->partition.band;
        r.fileBytes = a->fileBytes;
        r.memoryBytes = sizeof(NradAsset_) + a->asset.weights.size() * sizeof(float) +
                        a->asset.voxels.size() * (sizeof(format::VoxelEntry) + sizeof(float)) +
                        a->denseLookup.size() * sizeof(int32_t) +
                        a->partition.bytes() +
                        a->metadataCopy.size();
        *info = r;
        return NRAD_OK;
    });
}

NradStatus nradGetOccupiedVoxel(NradAsset a, uint32_t i, uint32_t* voxelIndex) {
    if (!a || !voxelIndex || i >= a->asset.voxels.size()) return NRAD_ERROR_INVALID_ARGUMENT;
    *voxelIndex = a->asset.voxels[i].index;
    return NRAD_OK;
}

NradStatus nradGetMetadata(NradAsset a, const char** json, size_t* length) {
    if (!a || !json || !length) return NRAD_ERROR_INVALID_ARGUMENT;
    *json = a->metadataLength ? a->metadata : "";
    *length = a->metadataLength;
    return NRAD_OK;
}

NradStatus nradEvaluate(NradAsset a, const float position[3], const float normal[3], const float direction[3], float rgb[3],
                        uint32_t* pointFlags) {
    if (!a || !position || !normal || !direction || !rgb) return NRAD_ERROR_INVALID_ARGUMENT;
    return guarded([&] {
        uint8_t flag = 0;
        rt::BatchIo v{{position, position + 1, position + 2}, {normal, normal + 1, normal + 2},
                      {direction, direction + 1, direction + 2}, {rgb, rgb + 1, rgb + 2}, 3, &flag, nullptr};
        NradStatus st = evaluateBatch(*a, 1, v);
        if (pointFlags) *pointFlags = flag;
        return st;
    });
}

NradStatus nradEvaluateBatch(NradAsset a, size_t count, const float* positions, const float* normals,
                             const float* directions, float* rgb, uint8_t* pointFlags) {
    if (!a || (count > 0 && (!positions || !normals || !directions || !rgb))) return NRAD_ERROR_INVALID_ARGUMENT;
    if (count == 0) return NRAD_OK;
    return guarded([&] {
        rt::BatchIo v{{positions, positions + 1, positions + 2}, {normals, normals + 1, normals + 2},
                      {directions, directions + 1, directions + 2}, {rgb, rgb + 1, rgb + 2}, 3, pointFlags, nullptr};
        return evaluateBatch(*a, count, v);
    });
}

NradStatus nradEvaluateBatchSoA(NradAsset a, size_t count, const NradBatchSoA* b) {
    if (!a || !b) return NRAD_ERROR_INVALID_ARGUMENT;
    if (count == 0) return NRAD_OK;
    if (!b->px || !b->py || !b->pz || !b->nx || !b->ny || !b->nz || !b->dx || !b->dy || !b->dz || !b->r || !b->g || !b->b)
        return NRAD_ERROR_INVALID_ARGUMENT;
    return guarded([&] {
        rt::BatchIo v{{b->px, b->py, b->pz}, {b->nx, b->ny, b->nz}, {b->dx, b->dy, b->dz}, {b->r, b->g, b->b}, 1, b->pointFlags, nullptr};
        return evaluateBatch(*a, count, v);
    });
}

NradStatus nradShadeBatch(NradAsset a, size_t count, const float* positions, const float* normals, const float* directions,
                          const NradSurface* surfaces, float* rgb, uint8_t* pointFlags) {
    if (!a || (count > 0 && (!positions || !normals || !directions || !surfaces || !rgb))) return NRAD_ERROR_INVALID_ARGUMENT;
    if (count == 0) return NRAD_OK;
    return guarded([&] {
        // A G-buffer of the batch's arrays, its vectors as given: the vector kernels read, evaluate, shade and
        // write each coherent vector in registers (the bits of evaluating, then shadeOne per point).
        NradGBuffer g;
        std::memset(&g, 0, sizeof g);
        g.structSize = sizeof g;
        g.flags = NRAD_GBUFFER_UNIT_VECTORS;
        g.count = count;
        g.position = {positions, 3 * sizeof(float), NRAD_FORMAT_F32};
        g.normal = {normals, 3 * sizeof(float), NRAD_FORMAT_F32};
        g.direction = {directions, 3 * sizeof(float), NRAD_FORMAT_F32};
        g.surfaces = surfaces;
        g.pointFlags = pointFlags;
        g.output = rgb;
        g.outputFormat = NRAD_FORMAT_F32;
        g.outputChannels = 3;
        shadeGBuffer(*a, g, threadScratch());
        return NRAD_OK;
    });
}

NradStatus nradShadeGBuffer(NradAsset a, const NradGBuffer* g, void* scratch, size_t scratchBytes) {
    if (!a || !g || g->structSize != sizeof(NradGBuffer)) return NRAD_ERROR_INVALID_ARGUMENT;
    if (g->count == 0) return NRAD_OK;
    const bool eye = (g->flags & NRAD_GBUFFER_EYE) != 0;
    auto valid = [](const NradAttribute& at) { return at.data && at.format <= NRAD_FORMAT_F16; };
    if ((g->flags & ~(NRAD_GBUFFER_EYE | NRAD_GBUFFER_UNIT_VECTORS)) || !valid(g->position) || !valid(g->normal) ||
        (!eye && !valid(g->direction)) || !g->output || g->outputFormat > NRAD_FORMAT_F16 ||
        (g->outputChannels != 3 && g->outputChannels != 4) || (scratch && scratchBytes < kScratchBytes + kGBufferScratchBytes))
        return NRAD_ERROR_INVALID_ARGUMENT;
    return guarded([&] {
        shadeGBuffer(*a, *g, scratch ? scratch : threadScratch());
        return NRAD_OK;
    });
}

NradStatus nradGetGpuBufferSize(NradAsset a, size_t* bytes) {
    if (!a || !bytes) return NRAD_ERROR_INVALID_ARGUMENT;
    gpu::Layout l;
    NradStatus st = gpu::layoutOf(*a, l);
    *bytes = st == NRAD_OK ? size_t(l.total) * 4 : 0;
    return st;
}

NradStatus nradPackGpuBuffer(NradAsset a, void* buffer, size_t capacity) {
    if (!a || !buffer) return NRAD_ERROR_INVALID_ARGUMENT;
    gpu::Layout l;
    if (NradStatus st = gpu::layoutOf(*a, l); st != NRAD_OK) return st;
    if (capacity < l.total * 4) return NRAD_ERROR_INVALID_ARGUMENT;
    if (reinterpret_cast<uintptr_t>(buffer) % 4 != 0) return NRAD_ERROR_INVALID_ARGUMENT;
    gpu::pack(*a, l, static_cast<uint32_t*>(buffer));
    return NRAD_OK;
}

void nradSetAllocator(NradAllocateFunction allocate, NradFreeFunction release, void* user) {
    const bool both = allocate && release;
    gAllocate.store(both ? allocate : defaultAllocate);
    gFree.store(both ? release : defaultFree);
    gAllocatorUser.store(both ? user : nullptr);
}

size_t nradGetScratchSize(void) { return kScratchBytes + kGBufferScratchBytes; }

NradStatus nradSelectKernel(NradKernel kernel) {
    if (kernel == NRAD_KERNEL_AUTO) {
        gKernel.store(bestKernel());
        return NRAD_OK;
    }
    if (kernel != NRAD_KERNEL_SCALAR && kernel != NRAD_KERNEL_AVX2 && kernel != NRAD_KERNEL_AVX512 && kernel != NRAD_KERNEL_NEON)
        return NRAD_ERROR_INVALID_ARGUMENT;
    if (!cpuHas(kernel)) return NRAD_ERROR_UNSUPPORTED_KERNEL;
    gKernel.store(kernel);
    return NRAD_OK;
}

NradKernel nradActiveKernel(void) { return activeKernel(); }

NradStatus nradSetAssetKernel(NradAsset a, NradKernel kernel) {
    if (!a || (kernel != NRAD_KERNEL_AUTO && kernel != NRAD_KERNEL_SCALAR && kernel != NRAD_KERNEL_AVX2 &&
               kernel != NRAD_KERNEL_AVX512 && kernel != NRAD_KERNEL_NEON))
        return NRAD_ERROR_INVALID_ARGUMENT;
    if (kernel != NRAD_KERNEL_AUTO && !cpuHas(kernel)) return NRAD_ERROR_UNSUPPORTED_KERNEL;
    a->kernel.store(kernel, std::memory_order_relaxed);
    return NRAD_OK;
}

int nradKernelSupported(NradKernel kernel) { return kernel == NRAD_KERNEL_AUTO || cpuHas(kernel) ? 1 : 0; }

}  // extern "C"
