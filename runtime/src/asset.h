// The loaded asset behind an NradAsset handle: the decoded file and the tables evaluation reads (internal).
#pragma once

#include <atomic>
#include <cstddef>
#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include <nrad/eval.h>
#include <nrad/format.h>
#include <nrad/nrad.h>

struct NradAsset_ {
    nrad::format::Asset asset;  // decoded; weights already in fp32
    uint64_t fileBytes = 0;
    std::string metadataCopy;  // NRAD_LOAD_COPY
    const char* metadata = nullptr;  // points into metadataCopy or, for NRAD_LOAD_BORROW, the caller's buffer
    size_t metadataLength = 0;
    uint32_t paramsPerNetwork = 0;
    std::vector<int32_t> denseLookup;  // cell -> network, -1 = empty; used when the grid is small enough
    nrad::eval::Partition partition;  // how a point finds its cells (the grid, or the kd-tree's leaves), its band
    std::vector<float> treeLeaves;  // kd-tree assets: rt::LocateTree::leaves (treeLeafBoxes)
    std::vector<int32_t> treeNodes, treeStarts;  // kd-tree assets: rt::LocateTree::nodes and starts (tagTree)
    std::vector<float> treeSplits;  // and rt::LocateTree::splits
    std::vector<int32_t> rectAxis, rectLeaves;  // small kd-trees: rt::LocateTree's rectilinear table (rectilinearTable)
    uint32_t rectOffset[3] = {0, 0, 0};
    std::vector<float> scales;  // per network: the voxel's output scale
    std::atomic<int> kernel{NRAD_KERNEL_AUTO};  // nradSetAssetKernel; AUTO: the process-wide choice
    // The volume's networks (VVOX, VWGT) as an asset of their own (the same cells, topology and tables, no
    // metadata): what nradEvaluateVolumeBatch evaluates with the normal as the direction. Null: none.
    std::unique_ptr<NradAsset_> volume;
    std::unique_ptr<NradAsset_> glossy;  // the volume's glossy response (VGLX, VGLW) likewise; null: none
};
