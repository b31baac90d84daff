// Loading an asset: the format's validating decoder, then the tables evaluation reads (kd-tree boxes and tags,
// the rectilinear table, the dense cell -> network table).
#include "asset_loading.h"

#include <algorithm>
#include <cstring>
#include <vector>

#include "asset.h"
#include "kernels.h"
#include "testing.h"

namespace nrad::rt {
namespace {

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
// both left empty past LocateTree::kMaxRectCells cells (testing::maxRectCells(), which the test build can lower).
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
        if (cells > testing::maxRectCells()) return;
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

// The tables evaluation reads: scales, the partition (taking the tree), the kd-tree's tables, the dense lookup.
void prepareTables(NradAsset_& a) {
    for (const format::VoxelEntry& e : a.asset.voxels) a.scales.push_back(e.scale);
    a.partition = eval::Partition(a.asset);
    std::vector<format::TreeNode>().swap(a.asset.tree);  // the partition holds it
    if (!a.partition.tree.empty()) {
        a.treeLeaves = treeLeafBoxes(a.partition);
        tagTree(a.partition, a.treeNodes, a.treeSplits, a.treeStarts);
        rectilinearTable(a.partition, a.rectAxis, a.rectLeaves, a.rectOffset);  // empty when too large
    }
    // A dense cell -> network table when it is small next to the networks themselves; else binary search.
    uint64_t voxels = a.partition.cells;
    if (voxels <= std::max<uint64_t>(1u << 16, uint64_t(a.asset.voxels.size()) * 64)) {
        a.denseLookup.assign(size_t(voxels), -1);
        for (size_t i = 0; i < a.asset.voxels.size(); ++i) a.denseLookup[a.asset.voxels[i].index] = int32_t(i);
    }
}

}  // namespace

void writeMessage(char* message, size_t size, const std::string& text) {
    if (!message || size == 0) return;
    size_t n = std::min(size - 1, text.size());
    std::memcpy(message, text.data(), n);
    message[n] = '\0';
}

NradStatus loadAsset(const void* data, size_t size, uint32_t flags, NradAsset* out, char* message, size_t messageSize) {
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
    // The volume's networks and its glossy response: each an asset of the same cells.
    auto cellsAsset = [&](std::vector<format::VoxelEntry>& voxels, std::vector<float>& weights) {
        auto sub = std::make_unique<NradAsset_>();
        format::Asset& v = sub->asset;
        v.header = a->asset.header;
        v.grid = a->asset.grid;
        v.topology = a->asset.topology;
        v.tree = a->asset.tree;
        v.leafCount = a->asset.leafCount;
        v.voxels.swap(voxels);
        v.weights.swap(weights);
        sub->paramsPerNetwork = a->paramsPerNetwork;
        prepareTables(*sub);
        return sub;
    };
    const format::OutputTransform volumeTransform = a->asset.volumeTransform();
    if (!a->asset.volumeVoxels.empty()) {
        a->volume = cellsAsset(a->asset.volumeVoxels, a->asset.volumeWeights);
        a->volume->asset.topology.outputTransform = volumeTransform;  // format::kFlagVolumeExponential
    }
    if (!a->asset.glossyVoxels.empty()) a->glossy = cellsAsset(a->asset.glossyVoxels, a->asset.glossyWeights);
    prepareTables(*a);
    *out = a;
    writeMessage(message, messageSize, "ok");
    return NRAD_OK;
}

}  // namespace nrad::rt
