// The asset packed for shading on a GPU (nrad.h "GPU buffers", docs/runtime.md): the header's fields at the
// words runtime/shaders/nrad_gpu_layout.h names, which nrad.glsl reads, then the sections.
#include "gpu_buffer.h"

#include <cstddef>
#include <cstring>
#include <vector>

#include <nrad_gpu_layout.h>

#include "asset.h"

namespace nrad::rt {
namespace {

// The header as the packer writes it. Each field sits at the word nrad_gpu_layout.h gives it (checked below),
// so the packer and nrad.glsl cannot disagree on an offset, and a new field cannot overlap another.
struct GpuHeader {
    uint32_t magic, version, contentFlags, outputTransform;
    float lower[3], upper[3];
    uint32_t dims[3];
    float factor[3];
    float band;
    uint32_t hiddenLayers, hiddenWidths[NRAD_MAX_HIDDEN_LAYERS];
    uint32_t paramsPerNetwork, networks, cells, treeNodes;
    uint32_t cellTable, scales, nodes, widths, boxes, weights, total;  // the sections' word offsets, the size
    uint32_t volumeNetworks, volumeCellTable, volumeScales, volumeWeights;  // 0 without volume networks
    uint32_t volumeOutputTransform;  // likewise
    uint32_t reserved[NRAD_GPU_HEADER_WORDS - NRAD_GPU_WORD_VOLUME_OUTPUT_TRANSFORM - 1];  // zero
};
#define NRAD_AT_WORD(field, word) static_assert(offsetof(GpuHeader, field) == 4 * (word), #field " is not at " #word)
NRAD_AT_WORD(magic, NRAD_GPU_WORD_MAGIC);
NRAD_AT_WORD(version, NRAD_GPU_WORD_VERSION);
NRAD_AT_WORD(contentFlags, NRAD_GPU_WORD_CONTENT_FLAGS);
NRAD_AT_WORD(outputTransform, NRAD_GPU_WORD_OUTPUT_TRANSFORM);
NRAD_AT_WORD(lower, NRAD_GPU_WORD_LOWER);
NRAD_AT_WORD(upper, NRAD_GPU_WORD_UPPER);
NRAD_AT_WORD(dims, NRAD_GPU_WORD_DIMS);
NRAD_AT_WORD(factor, NRAD_GPU_WORD_FACTOR);
NRAD_AT_WORD(band, NRAD_GPU_WORD_BAND);
NRAD_AT_WORD(hiddenLayers, NRAD_GPU_WORD_HIDDEN_LAYERS);
NRAD_AT_WORD(hiddenWidths, NRAD_GPU_WORD_HIDDEN_WIDTHS);
NRAD_AT_WORD(paramsPerNetwork, NRAD_GPU_WORD_PARAMS);
NRAD_AT_WORD(networks, NRAD_GPU_WORD_NETWORKS);
NRAD_AT_WORD(cells, NRAD_GPU_WORD_CELLS);
NRAD_AT_WORD(treeNodes, NRAD_GPU_WORD_TREE_NODES);
NRAD_AT_WORD(cellTable, NRAD_GPU_WORD_CELL_TABLE);
NRAD_AT_WORD(scales, NRAD_GPU_WORD_SCALES);
NRAD_AT_WORD(nodes, NRAD_GPU_WORD_NODES);
NRAD_AT_WORD(widths, NRAD_GPU_WORD_WIDTHS);
NRAD_AT_WORD(boxes, NRAD_GPU_WORD_BOXES);
NRAD_AT_WORD(weights, NRAD_GPU_WORD_WEIGHTS);
NRAD_AT_WORD(total, NRAD_GPU_WORD_TOTAL);
NRAD_AT_WORD(volumeNetworks, NRAD_GPU_WORD_VOLUME_NETWORKS);
NRAD_AT_WORD(volumeCellTable, NRAD_GPU_WORD_VOLUME_CELL_TABLE);
NRAD_AT_WORD(volumeScales, NRAD_GPU_WORD_VOLUME_SCALES);
NRAD_AT_WORD(volumeWeights, NRAD_GPU_WORD_VOLUME_WEIGHTS);
NRAD_AT_WORD(volumeOutputTransform, NRAD_GPU_WORD_VOLUME_OUTPUT_TRANSFORM);
#undef NRAD_AT_WORD
static_assert(sizeof(GpuHeader) == 4 * NRAD_GPU_HEADER_WORDS, "the header is NRAD_GPU_HEADER_WORDS words");
static_assert(NRAD_GPU_TREE_LEAF == format::kTreeLeaf, "tree nodes are packed as the file's TREE records");

uint32_t bitsOf(float f) {
    uint32_t u;
    std::memcpy(&u, &f, 4);
    return u;
}

GpuHeader headerOf(const NradAsset_& a, const GpuLayout& l) {
    const format::Grid& g = a.asset.grid;
    const format::Topology& t = a.asset.topology;
    GpuHeader h;
    std::memset(&h, 0, sizeof h);
    h.magic = NRAD_GPU_MAGIC;
    h.version = NRAD_GPU_LAYOUT_VERSION;
    h.contentFlags = a.asset.header.flags & format::kKnownFlags;
    h.outputTransform = uint32_t(t.outputTransform);
    for (int k = 0; k < 3; ++k) {
        h.lower[k] = g.lower[k];
        h.upper[k] = g.upper[k];
        h.dims[k] = g.dims[k];
        h.factor[k] = a.partition.factor[k];
    }
    h.band = a.partition.band;
    h.hiddenLayers = uint32_t(t.hiddenWidths.size());
    for (size_t i = 0; i < t.hiddenWidths.size(); ++i) h.hiddenWidths[i] = t.hiddenWidths[i];
    h.paramsPerNetwork = a.paramsPerNetwork;
    h.networks = uint32_t(a.asset.voxels.size());
    h.cells = uint32_t(a.partition.cells);
    h.treeNodes = uint32_t(a.partition.tree.size());
    h.cellTable = uint32_t(l.cellTable);
    h.scales = uint32_t(l.scales);
    h.nodes = uint32_t(l.nodes);
    h.widths = uint32_t(l.widths);
    h.boxes = uint32_t(l.boxes);
    h.weights = uint32_t(l.weights);
    h.total = uint32_t(l.total);
    if (a.volume) {
        h.volumeNetworks = uint32_t(a.volume->asset.voxels.size());
        h.volumeCellTable = uint32_t(l.volumeCellTable);
        h.volumeScales = uint32_t(l.volumeScales);
        h.volumeWeights = uint32_t(l.volumeWeights);
        h.volumeOutputTransform = uint32_t(a.volume->asset.topology.outputTransform);
    }
    return h;
}

}  // namespace

NradStatus gpuLayoutOf(const NradAsset_& a, GpuLayout& l) {
    const format::Topology& t = a.asset.topology;
    for (uint32_t w : t.hiddenWidths)
        if (w > NRAD_GPU_MAX_HIDDEN_WIDTH) return NRAD_ERROR_UNSUPPORTED_GPU_LAYOUT;
    if (t.hiddenWidths.size() > NRAD_MAX_HIDDEN_LAYERS || a.partition.cells > NRAD_GPU_MAX_CELLS)
        return NRAD_ERROR_UNSUPPORTED_GPU_LAYOUT;
    const uint64_t nodes = a.partition.tree.size(), leaves = a.partition.tree.empty() ? 0 : a.partition.cells;
    const uint64_t halves = uint64_t(a.asset.voxels.size()) * a.paramsPerNetwork;
    l.cellTable = NRAD_GPU_HEADER_WORDS;
    l.scales = l.cellTable + a.partition.cells;
    l.nodes = l.scales + a.asset.voxels.size();
    l.widths = l.nodes + 2 * nodes;
    l.boxes = l.widths + nodes;
    l.weights = l.boxes + 6 * leaves;
    l.total = l.weights + (halves + 1) / 2;
    if (a.volume) {  // the volume's table, scales and weights after the surfaces'
        const uint64_t volumeNetworks = a.volume->asset.voxels.size();
        l.volumeCellTable = l.total;
        l.volumeScales = l.volumeCellTable + a.partition.cells;
        l.volumeWeights = l.volumeScales + volumeNetworks;
        l.total = l.volumeWeights + (volumeNetworks * a.paramsPerNetwork + 1) / 2;
    }
    return l.total * 4 <= UINT32_MAX ? NRAD_OK : NRAD_ERROR_UNSUPPORTED_GPU_LAYOUT;  // offsets are 32-bit words
}

void packGpuBuffer(const NradAsset_& a, const GpuLayout& l, uint32_t* w) {
    std::memset(w, 0, size_t(l.total) * 4);
    const GpuHeader h = headerOf(a, l);
    std::memcpy(w, &h, sizeof h);
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
    if (!a.volume) return;
    const NradAsset_& v = *a.volume;
    for (uint64_t c = 0; c < a.partition.cells; ++c) w[l.volumeCellTable + c] = UINT32_MAX;
    for (size_t i = 0; i < v.asset.voxels.size(); ++i) {
        w[l.volumeCellTable + v.asset.voxels[i].index] = uint32_t(i);
        w[l.volumeScales + i] = bitsOf(v.scales[i]);
    }
    for (size_t i = 0; i < v.asset.weights.size(); ++i)
        w[l.volumeWeights + i / 2] |= uint32_t(format::floatToHalf(v.asset.weights[i])) << (16 * (i & 1));
}

}  // namespace nrad::rt
