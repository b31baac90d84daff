// Hooks for the runtime's own tests, compiled only into its test build (the nrad_runtime_testing target, which
// defines NRAD_RUNTIME_TESTING): which vector paths blocks took, and the rectilinear table's size limit. The
// shipped library has none of them: there the hooks below are constants and empty functions.
#pragma once

#include <cstddef>
#include <cstdint>

#include "kernels.h"

namespace nrad::rt::testing {

#ifdef NRAD_RUNTIME_TESTING
// Blocks blended in registers since the process started, over all threads: lets tests see that the vector
// blending path is taken (its results are bit-identical to the general path's by design).
uint64_t blendedBlocksSoFar();
// G-buffer blocks read, evaluated and written in registers since the process started (the same purpose).
uint64_t gbufferBlocksSoFar();
// Blocks of kd-tree assets located and evaluated in registers since the process started (the same purpose).
uint64_t treeBlocksSoFar();
// The most cells of a kd-tree's rectilinear table (LocateTree) for assets loaded from now on; tests set 0 to
// run the start table's descent on small trees (default LocateTree::kMaxRectCells).
void setMaxRectCells(size_t cells);

// For the runtime: the limit above, and a block driver's counts added to the totals.
size_t maxRectCells();
void countBlocks(const Deferred& def);
#else
inline size_t maxRectCells() { return LocateTree::kMaxRectCells; }
inline void countBlocks(const Deferred&) {}
#endif

}  // namespace nrad::rt::testing
