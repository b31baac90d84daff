// The runtime's test hooks (testing.h), in its test build only (nrad_runtime_testing).
#include "testing.h"

#include <atomic>

#ifndef NRAD_RUNTIME_TESTING
#error "testing.cpp belongs to the runtime's test build (NRAD_RUNTIME_TESTING)"
#endif

namespace nrad::rt::testing {
namespace {
std::atomic<uint64_t> gBlendedBlocks{0};
std::atomic<uint64_t> gGBufferBlocks{0};
std::atomic<uint64_t> gTreeBlocks{0};
std::atomic<size_t> gMaxRectCells{LocateTree::kMaxRectCells};
}  // namespace

uint64_t blendedBlocksSoFar() { return gBlendedBlocks.load(std::memory_order_relaxed); }
uint64_t gbufferBlocksSoFar() { return gGBufferBlocks.load(std::memory_order_relaxed); }
uint64_t treeBlocksSoFar() { return gTreeBlocks.load(std::memory_order_relaxed); }
void setMaxRectCells(size_t cells) { gMaxRectCells.store(cells, std::memory_order_relaxed); }
size_t maxRectCells() { return gMaxRectCells.load(std::memory_order_relaxed); }

void countBlocks(const Deferred& def) {
    if (def.blendedBlocks) gBlendedBlocks.fetch_add(def.blendedBlocks, std::memory_order_relaxed);
    if (def.gbufferBlocks) gGBufferBlocks.fetch_add(def.gbufferBlocks, std::memory_order_relaxed);
    if (def.treeBlocks) gTreeBlocks.fetch_add(def.treeBlocks, std::memory_order_relaxed);
}

}  // namespace nrad::rt::testing
