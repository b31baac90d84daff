// Random kd-trees over a lattice, for the partition tests: valid by construction (splits strictly inside
// their box, children after their parent, leaves numbered depth first).
#pragma once

#include <cstdint>
#include <random>
#include <vector>

#include <nrad/format.h>

namespace nrad::test {

// Splits boxes at random lattice planes until `leaves` leaves (or nothing is splittable), deeper where the
// random draw says; a box is split along a random axis that is at least 2 voxels long.
inline std::vector<format::TreeNode> randomTree(const uint32_t dims[3], uint32_t leaves, uint32_t seed) {
    std::mt19937 rng(seed);
    struct Cell {
        format::TreeBox box;
        int lower = -1, upper = -1;
        uint32_t axis = 0, split = 0;
    };
    std::vector<Cell> cells(1);
    for (int k = 0; k < 3; ++k) cells[0].box.hi[k] = dims[k];
    std::vector<size_t> open = {0};
    uint32_t count = 1;
    while (count < leaves && !open.empty()) {
        const size_t pick = rng() % open.size();
        const size_t c = open[pick];
        uint32_t axes[3], n = 0;
        for (uint32_t k = 0; k < 3; ++k)
            if (cells[c].box.hi[k] - cells[c].box.lo[k] >= 2) axes[n++] = k;
        if (n == 0) {
            open.erase(open.begin() + long(pick));
            continue;
        }
        const uint32_t k = axes[rng() % n];
        const format::TreeBox b = cells[c].box;
        const uint32_t split = b.lo[k] + 1 + uint32_t(rng() % (b.hi[k] - b.lo[k] - 1));
        Cell lo, hi;
        lo.box = hi.box = b;
        lo.box.hi[k] = split;
        hi.box.lo[k] = split;
        cells[c].axis = k;
        cells[c].split = split;
        cells[c].lower = int(cells.size());
        cells.push_back(lo);
        cells[c].upper = int(cells.size());
        cells.push_back(hi);
        open.erase(open.begin() + long(pick));
        open.push_back(size_t(cells[c].lower));
        open.push_back(size_t(cells[c].upper));
        ++count;
    }
    // Emit depth first with children adjacent.
    std::vector<format::TreeNode> nodes(1);
    uint32_t leaf = 0;
    struct Emit {
        const std::vector<Cell>& cells;
        std::vector<format::TreeNode>& nodes;
        uint32_t& leaf;
        void operator()(size_t c, uint32_t at) {
            if (cells[c].lower < 0) {
                nodes[at] = {format::kTreeLeaf, 0, leaf++};
                return;
            }
            const uint32_t child = uint32_t(nodes.size());
            nodes.resize(nodes.size() + 2);
            nodes[at] = {cells[c].axis, cells[c].split, child};
            (*this)(size_t(cells[c].lower), child);
            (*this)(size_t(cells[c].upper), child + 1);
        }
    };
    Emit{cells, nodes, leaf}(0, 0);
    return nodes;
}

// `a` made a kd-tree asset over a dims^3 lattice of its box: randomTree(leaves, seed), a network on every leaf
// but each `skip`-th from `offset` (skip 0: every leaf), scales 0.5 + 0.01 leaf, fp16-exact weights in
// [-0.6, 0.6] from `seed`, every hardEvery-th inner node hard (0: none). Returns the leaves' boxes (empty if the tree were invalid, which randomTree's never is).
inline std::vector<format::TreeBox> makeRandomTreeAsset(format::Asset& a, uint32_t dims, uint32_t leaves, uint32_t seed,
                                                        uint32_t skip = 0, uint32_t offset = 0, uint32_t hardEvery = 0) {
    for (int k = 0; k < 3; ++k) a.grid.dims[k] = dims;
    a.header.flags |= format::kFlagTree;
    a.tree = randomTree(a.grid.dims, leaves, seed);
    for (size_t i = 0; i < a.tree.size(); ++i)  // hardEvery > 0: every hardEvery-th node, if inner, hard (no band)
        a.tree[i].hard = hardEvery > 0 && i % hardEvery == 0 && a.tree[i].axis != format::kTreeLeaf;
    uint32_t count = 0;
    std::vector<format::TreeBox> boxes;
    if (!format::validateTree(a.grid.dims, a.tree, count, &boxes)) return {};
    a.voxels.clear();
    for (uint32_t v = 0; v < count; ++v)
        if (skip == 0 || v % skip != offset) a.voxels.push_back({v, 0.5f + 0.01f * float(v)});
    std::mt19937 rng(seed);
    a.weights.resize(a.voxels.size() * a.topology.parameterCount());
    for (float& w : a.weights) w = format::halfToFloat(format::floatToHalf(float(int(rng() % 1201) - 600) / 1000.0f));
    return boxes;
}

}  // namespace nrad::test
