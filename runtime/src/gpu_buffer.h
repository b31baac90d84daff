// The asset packed for shading on a GPU (nrad.h "GPU buffers"): the buffer's sections and their packing.
#pragma once

#include <cstdint>

#include <nrad/nrad.h>

namespace nrad::rt {

// The sections' word offsets in the buffer, and its size in words.
struct GpuLayout {
    uint64_t cellTable, scales, nodes, widths, boxes, weights, total;
    uint64_t volumeCellTable = 0, volumeScales = 0, volumeWeights = 0;  // the light in the volume (0: none)
};

// The asset's layout; NRAD_ERROR_UNSUPPORTED_GPU_LAYOUT beyond the layout's limits.
NradStatus gpuLayoutOf(const NradAsset_& a, GpuLayout& l);
// Writes the packed buffer (l.total words at `w`, 4-byte aligned).
void packGpuBuffer(const NradAsset_& a, const GpuLayout& l, uint32_t* w);

}  // namespace nrad::rt
