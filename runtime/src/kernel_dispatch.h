// The evaluation kernels as one table (what each needs of the CPU, its entry points, its vector width) and the
// choice among them: process-wide (nradSelectKernel) or per asset (nradSetAssetKernel). Every place that
// depends on which kernel runs reads the table; a new kernel is one row of kKernels (kernel_dispatch.cpp),
// its kernel_*.cpp, its entry points declared in kernels.h and its NradKernel value in nrad.h.
#pragma once

#include <nrad/nrad.h>

#include "kernels.h"

struct NradAsset_;

namespace nrad::rt {

struct KernelEntry {
    NradKernel id;
    // Whether this CPU can run it; null where this build has no such kernel (another architecture's). It runs
    // no instruction of the kernel: the kernels' files are compiled for their instruction sets, this one is not.
    bool (*supported)();
    ChunkKernel evalChunk;  // one network over a chunk of points (kernels.h)
    BlockDriver evalBlocks;  // whole vectors of points through locating and evaluation; null: none
    int blockWidth;  // points per vector of evalBlocks
    HalfToFloat halfToFloat;  // fp16 conversions of G-buffers
    FloatToHalf floatToHalf;
    // Whether this CPU has those conversions (null: whenever it runs the kernel); where not, the scalar ones.
    bool (*halfSupported)();
};

// The entry of a kernel the API names (any architecture's), or null (NRAD_KERNEL_AUTO, or not a kernel).
const KernelEntry* findKernel(NradKernel k);
// The entry evaluation runs for a kernel that was checked (nradSelectKernel, nradSetAssetKernel): its own, or
// the scalar one where this build lacks it.
const KernelEntry& kernelEntry(NradKernel k);
// Nonzero if this CPU and build can run k (false for AUTO and for values that name no kernel).
bool kernelSupported(NradKernel k);
// The first kernel of the table (fastest first) this CPU supports.
NradKernel bestKernel();

// The process-wide kernel (never AUTO: chosen on first use), and setting it (never to AUTO).
NradKernel activeKernel();
void setActiveKernel(NradKernel k);
// The asset's own kernel (nradSetAssetKernel), else the process-wide one.
NradKernel kernelOf(const NradAsset_& a);

// fp16 conversions: the kernel's own where the CPU has them, else the format's scalar ones.
struct HalfConverters {
    HalfToFloat toFloat;
    FloatToHalf toHalf;
};
HalfConverters halfConverters(NradKernel k);

}  // namespace nrad::rt
