// Evaluation of a batch, tile by tile: the scratch a tile works in (the caller's, or the thread's through the
// allocator hook), and a tile's points through the kernels' block driver and the grouped pass.
#pragma once

#include <cstddef>
#include <cstdint>

#include <nrad/eval.h>
#include <nrad/nrad.h>

#include "kernels.h"

struct NradAsset_;

namespace nrad::rt {

// ----- scratch: everything evaluation needs besides the caller's arrays --------------------------------------

// Evaluation works on tiles of at most kTilePoints points; a tile's deferred entries (point, network, weight,
// position in the network's cell) number at most kMaxSupports per point. All of it lives in one block of
// memory carved into the arrays below: the caller's (nradGetScratchSize), or a per-thread block allocated
// once through the allocator hook and reused.
constexpr size_t kTilePoints = 1024;
constexpr size_t kTileEntries = kTilePoints * eval::kMaxSupports;

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

// The scratch block's arrays (`memory`: kScratchBytes, any alignment).
Scratch carveScratch(void* memory);
// The calling thread's scratch block (one per thread, shared by every entry point), allocated through the
// allocator hook on its first use.
void* threadScratch();
// nradSetAllocator: the hook for threads' scratch blocks from now on (null functions: malloc/free).
void setScratchAllocator(NradAllocateFunction allocate, NradFreeFunction release, void* user);

// ----- evaluation ----------------------------------------------------------------------------------------------

// The asset's block driver and its width: on a vector kernel, for assets with a dense cell -> network table
// (kd-trees: with their start table too); else null and 0.
BlockDriver blockDriverOf(const NradAsset_& a, int& width);
// At most kTilePoints points of `v` in `s`.
void evaluateTile(const NradAsset_& a, size_t count, const BatchIo& v, Scratch& s);
// A batch, tile by tile, in `scratch` (kScratchBytes), or the calling thread's scratch when null.
NradStatus evaluateBatch(const NradAsset_& a, size_t count, const BatchIo& v, void* scratch = nullptr);

}  // namespace nrad::rt
