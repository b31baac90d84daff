// The kd-tree partition (format 2.2, kFlagTree): the uniform tree is the grid bit for bit (supports, weights,
// position inputs), any tree's blend weights are a partition of unity that is continuous across leaves of
// different sizes, and the decoder refuses cyclic, shared, out-of-range, overlapping, unreached and too deep
// trees, a tree without its flag and a flag without its tree.
#include <nrad/eval.h>
#include <nrad/format.h>

#include <cmath>
#include <cstring>
#include <limits>
#include <random>

#include <gtest/gtest.h>

#include "support/test_trees.h"

namespace nrad::format {
namespace {

Grid latticeGrid(uint32_t x, uint32_t y, uint32_t z) {
    Grid g;
    const uint32_t d[3] = {x, y, z};
    for (int k = 0; k < 3; ++k) {
        g.lower[k] = -1.0f - 0.5f * float(k);
        g.upper[k] = 2.0f + 0.25f * float(k);
        g.dims[k] = d[k];
    }
    return g;
}

// Random points in (and slightly around) the grid, a third of them placed on or near lattice planes.
std::vector<std::array<float, 3>> probePoints(const Grid& g, size_t count, uint32_t seed) {
    std::mt19937 rng(seed);
    std::uniform_real_distribution<float> u(0.0f, 1.0f);
    std::vector<std::array<float, 3>> out;
    for (size_t i = 0; i < count; ++i) {
        std::array<float, 3> p;
        for (int k = 0; k < 3; ++k) {
            const float size = (g.upper[k] - g.lower[k]) / float(g.dims[k]);
            float t = u(rng) * float(g.dims[k]);
            if (rng() % 3 == 0) t = std::round(t) + (u(rng) - 0.5f) * 0.3f;  // near a plane
            if (rng() % 11 == 0) t = std::round(t);  // on one
            p[size_t(k)] = g.lower[k] + size * t;
        }
        if (rng() % 50 == 0) p[0] = g.upper[0] + 0.1f;  // outside
        out.push_back(p);
    }
    return out;
}

TEST(Tree, UniformTreeIsTheGridBitForBit) {
    for (auto d : {std::array<uint32_t, 3>{1, 1, 1}, {3, 2, 5}, {4, 4, 4}, {7, 1, 3}, {2, 9, 2}}) {
        const Grid g = latticeGrid(d[0], d[1], d[2]);
        const std::vector<TreeNode> tree = uniformTree(g.dims);
        uint32_t leaves = 0;
        std::vector<TreeBox> boxes;
        ASSERT_TRUE(validateTree(g.dims, tree, leaves, &boxes));
        ASSERT_EQ(leaves, g.voxelCount());
        EXPECT_EQ(tree.size(), 2 * g.voxelCount() - 1);
        for (uint32_t v = 0; v < leaves; ++v) {
            const uint32_t c[3] = {v % d[0], (v / d[0]) % d[1], v / (d[0] * d[1])};
            for (int k = 0; k < 3; ++k) {
                EXPECT_EQ(boxes[v].lo[k], c[k]);
                EXPECT_EQ(boxes[v].hi[k], c[k] + 1);
            }
        }
        for (float band : {0.0f, 0.0625f, 0.25f, 0.5f}) {
            const eval::Partition grid(g, band, {}, 0), kd(g, band, tree, leaves);
            for (const auto& p : probePoints(g, 4000, d[0] * 7 + d[2])) {
                eval::Support a[eval::kMaxSupports], b[eval::kMaxSupports];
                const int na = grid.supports(p.data(), a), nb = kd.supports(p.data(), b);
                ASSERT_EQ(na, nb);
                for (int i = 0; i < na; ++i) {
                    ASSERT_EQ(a[i].voxel, b[i].voxel);
                    ASSERT_EQ(std::memcmp(&a[i].weight, &b[i].weight, 4), 0) << band;
                    ASSERT_EQ(std::memcmp(a[i].local, b[i].local, 12), 0) << band;
                }
                EXPECT_EQ(grid.cellOf(p.data()), kd.cellOf(p.data()));
            }
        }
    }
}

TEST(Tree, BlendWeightsArePartitionsOfUnityAcrossLeavesOfDifferentSizes) {
    const Grid g = latticeGrid(16, 8, 12);
    for (uint32_t seed = 1; seed <= 6; ++seed) {
        const std::vector<TreeNode> tree = test::randomTree(g.dims, 40 + 20 * seed, seed);
        uint32_t leaves = 0;
        std::vector<TreeBox> boxes;
        ASSERT_TRUE(validateTree(g.dims, tree, leaves, &boxes));
        const float band = 0.25f;
        const eval::Partition kd(g, band, tree, leaves);
        // Widths: at most band x the extent of every leaf touching the plane.
        std::mt19937 rng(seed);
        std::vector<float> value(leaves);
        for (float& v : value) v = float(rng() % 1000) / 100.0f;
        auto field = [&](const float p[3], int& n) {
            eval::Support s[eval::kMaxSupports];
            n = kd.supports(p, s);
            double sum = 0.0, f = 0.0;
            for (int i = 0; i < n; ++i) {
                sum += s[i].weight;
                f += double(s[i].weight) * value[size_t(s[i].voxel)];
                const TreeBox& b = boxes[size_t(s[i].voxel)];
                for (int k = 0; k < 3; ++k) {  // the leaf reaches p within its bands
                    EXPECT_LE(std::abs(s[i].local[k]), 1.0f + 2.0f * band + 1e-5f);
                    const float t = (p[k] - g.lower[k]) * eval::gridFactor(g, k);
                    const float extent = float(b.hi[k] - b.lo[k]);
                    EXPECT_GE(t, float(b.lo[k]) - band * extent - 1e-4f);
                    EXPECT_LE(t, float(b.hi[k]) + band * extent + 1e-4f);
                }
                if (i > 0) {
                    EXPECT_LT(s[i - 1].voxel, s[i].voxel);
                }
            }
            if (n > 0) {
                EXPECT_NEAR(sum, 1.0, 1e-6);
            }
            return f;
        };
        for (const auto& p : probePoints(g, 3000, seed)) {
            int n = 0;
            const double f = field(p.data(), n);
            EXPECT_LE(n, eval::kMaxSupports);
            if (n == 0) continue;
            // Continuity: a step of 1e-4 voxels changes the blended field by at most its slope bound
            // (smoothstep 1.5 / (2 w) per voxel per plane, w >= band; 3 axes, values below 10).
            for (int k = 0; k < 3; ++k) {
                std::array<float, 3> q = p;
                q[size_t(k)] += 1e-4f / eval::gridFactor(g, k);
                int m = 0;
                const double h = field(q.data(), m);
                if (m == 0) continue;
                EXPECT_LE(std::abs(h - f), 10.0 * 3.0 * 1.5 / (2.0 * band) * 1e-4 * 1.05 + 1e-4) << seed;
            }
        }
    }
}

// The start table is an acceleration only: every point gets the supports of the descent from the root, bit
// for bit, for blended and unblended trees of many shapes.
TEST(Tree, StartTableGivesTheRootDescentsSupports) {
    const Grid g = latticeGrid(40, 24, 33);
    for (uint32_t seed = 1; seed <= 5; ++seed) {
        const std::vector<TreeNode> tree = test::randomTree(g.dims, 30 * seed * seed, seed);
        uint32_t leaves = 0;
        ASSERT_TRUE(validateTree(g.dims, tree, leaves));
        for (float band : {0.0f, 0.0625f, 0.5f}) {
            const eval::Partition fast(g, band, tree, leaves), plain(g, band, tree, leaves, false);
            ASSERT_FALSE(fast.starts.empty());
            ASSERT_TRUE(plain.starts.empty());
            for (const auto& p : probePoints(g, 5000, seed + 100)) {
                eval::Support a[eval::kMaxSupports], b[eval::kMaxSupports];
                const int na = fast.supports(p.data(), a), nb = plain.supports(p.data(), b);
                ASSERT_EQ(na, nb);
                for (int i = 0; i < na; ++i) {
                    ASSERT_EQ(a[i].voxel, b[i].voxel);
                    ASSERT_EQ(std::memcmp(&a[i].weight, &b[i].weight, 4), 0);
                    ASSERT_EQ(std::memcmp(a[i].local, b[i].local, 12), 0);
                }
            }
        }
    }
}

std::vector<uint8_t> treeAssetBytes(const std::vector<TreeNode>& tree, uint32_t leaves, uint32_t flags = kFlagTree) {
    Asset a;
    a.grid = latticeGrid(4, 4, 4);
    a.header.flags = kFlagScatteredRadiance | flags;
    a.topology.hiddenWidths = {2};
    a.tree = tree;
    for (uint32_t i = 0; i < leaves; i += 2) a.voxels.push_back({i, 1.0f});
    a.weights.assign(a.voxels.size() * a.topology.parameterCount(), 0.125f);
    return encodeUnchecked(a);  // the trees may be invalid on purpose
}

TEST(Tree, RoundTripsAsVersionTwoPointTwo) {
    const Grid g = latticeGrid(4, 4, 4);
    const std::vector<TreeNode> tree = test::randomTree(g.dims, 20, 3);
    uint32_t leaves = 0;
    ASSERT_TRUE(validateTree(g.dims, tree, leaves));
    const std::vector<uint8_t> b = treeAssetBytes(tree, leaves);
    EXPECT_EQ(b[10], 2);  // minor version
    Asset out;
    ASSERT_EQ(decode(b.data(), b.size(), out), DecodeStatus::Ok);
    EXPECT_EQ(out.leafCount, leaves);
    ASSERT_EQ(out.tree.size(), tree.size());
    for (size_t i = 0; i < tree.size(); ++i) {
        EXPECT_EQ(out.tree[i].axis, tree[i].axis);
        EXPECT_EQ(out.tree[i].split, tree[i].split);
        EXPECT_EQ(out.tree[i].child, tree[i].child);
    }
    EXPECT_EQ(out.cellCount(), leaves);
}

// A hard plane (TreeNode::hard, version 2.3): the flag round-trips in the child word's top bit, its node has
// no band, so points beside it have the one leaf on their side; a leaf marked hard is refused.
TEST(Tree, HardPlanesRoundTripAsTwoPointThreeAndNoBandCrossesThem) {
    const Grid g = latticeGrid(4, 4, 4);
    // The root cuts x at 2 (hard), its lower child cuts y at 2 (soft): three leaves.
    std::vector<TreeNode> tree = {{0, 2, 1, true}, {1, 2, 3}, {kTreeLeaf, 0, 2}, {kTreeLeaf, 0, 0}, {kTreeLeaf, 0, 1}};
    uint32_t leaves = 0;
    ASSERT_TRUE(validateTree(g.dims, tree, leaves));
    ASSERT_EQ(leaves, 3u);
    const std::vector<uint8_t> b = treeAssetBytes(tree, leaves);
    EXPECT_EQ(b[10], 3);  // minor version
    Asset out;
    ASSERT_EQ(decode(b.data(), b.size(), out), DecodeStatus::Ok);
    ASSERT_EQ(out.tree.size(), tree.size());
    for (size_t i = 0; i < tree.size(); ++i) {
        EXPECT_EQ(out.tree[i].child, tree[i].child);
        EXPECT_EQ(out.tree[i].hard, tree[i].hard);
    }
    const float band = 0.25f;
    const std::vector<float> widths = eval::treeBandWidths(g.dims, out.tree, band);
    EXPECT_EQ(widths[0], 0.0f);
    EXPECT_EQ(widths[1], band * 2.0f);  // the leaves beside y = 2 are 2 wide
    const eval::Partition kd(g, band, out.tree, leaves);
    auto supportsAt = [&](float tx, float ty) {
        const float p[3] = {g.lower[0] + tx / eval::gridFactor(g, 0), g.lower[1] + ty / eval::gridFactor(g, 1),
                            g.lower[2] + 1.0f / eval::gridFactor(g, 2)};
        eval::Support s[eval::kMaxSupports];
        return kd.supports(p, s);
    };
    EXPECT_EQ(supportsAt(1.95f, 1.0f), 1);  // beside the hard plane, on either side: one leaf
    EXPECT_EQ(supportsAt(2.05f, 1.0f), 1);
    EXPECT_EQ(supportsAt(1.0f, 1.95f), 2);  // beside the soft one: both
    // The same tree without the flag: 2.2, and a band at the root.
    tree[0].hard = false;
    EXPECT_EQ(treeAssetBytes(tree, leaves)[10], 2);
    EXPECT_EQ(eval::treeBandWidths(g.dims, tree, band)[0], band * 2.0f);
    // A leaf cannot be hard.
    tree[2].hard = true;
    EXPECT_FALSE(validateTree(g.dims, tree, leaves));
}

// A partition is built from a valid tree with its true leaf count (the decoder validates an asset's; the
// baker builds its own valid): anything else is a bug, stopped where it would have read the wrong leaves.
TEST(TreeDeathTest, PartitionStopsAtAnInvalidTreeOrLeafCount) {
    const Grid g = latticeGrid(4, 4, 4);
    const std::vector<TreeNode> good = uniformTree(g.dims);  // 64 leaves
    EXPECT_EQ(eval::Partition(g, 0.25f, good, 64).cells, 64u);
    EXPECT_DEATH(eval::Partition(g, 0.25f, good, 63), "internal check failed: valid && leaves == leafCount");
    std::vector<TreeNode> cycle = good;
    cycle[0].child = 0;
    EXPECT_DEATH(eval::Partition(g, 0.25f, cycle, 64), "internal check failed: valid");
}

TEST(Tree, DecoderRefusesInvalidTrees) {
    const uint32_t dims[3] = {4, 4, 4};
    const std::vector<TreeNode> good = uniformTree(dims);  // 64 leaves, 127 nodes
    uint32_t leaves = 0;
    ASSERT_TRUE(validateTree(dims, good, leaves));
    Asset out;
    auto status = [&](const std::vector<TreeNode>& t, uint32_t flags = kFlagTree) {
        const std::vector<uint8_t> b = treeAssetBytes(t, 4, flags);
        return decode(b.data(), b.size(), out);
    };
    ASSERT_EQ(status(good), DecodeStatus::Ok);
    std::vector<TreeNode> t = good;
    t[0].child = 0;  // a cycle back to the root
    EXPECT_EQ(status(t), DecodeStatus::BadTree);
    t = good;
    t[2] = t[1];  // both children of the root share one subtree
    EXPECT_EQ(status(t), DecodeStatus::BadTree);
    t = good;
    t[0].child = uint32_t(t.size() - 1);  // the upper child out of range
    EXPECT_EQ(status(t), DecodeStatus::BadTree);
    t = good;
    t[0].split = 4;  // on the box's face: an empty child
    EXPECT_EQ(status(t), DecodeStatus::BadTree);
    t = good;
    t[1].split = 3;  // the lower child of z < 2 cut at z = 3: outside its box, its leaves would overlap the upper's
    EXPECT_EQ(status(t), DecodeStatus::BadTree);
    t = good;
    t[0].axis = 7 & 3;  // a leaf where a node should be: 126 nodes unreached
    t[0].child = 0;
    t[0].split = 0;
    EXPECT_EQ(status(t), DecodeStatus::BadTree);
    t = good;
    std::swap(t[t.size() - 1].child, t[t.size() - 2].child);  // leaves out of depth-first order
    EXPECT_EQ(status(t), DecodeStatus::BadTree);
    t = good;
    t.back().split = 1;  // a leaf with split bits set
    EXPECT_EQ(status(t), DecodeStatus::BadTree);
    // Flag and section go together.
    {  // a TREE section without the flag (the header's flag cleared, its CRC fixed)
        std::vector<uint8_t> b = treeAssetBytes(good, 4);
        b[12] = uint8_t(b[12] & ~kFlagTree);
        const uint32_t crc = crc32(b.data(), 60);
        for (int i = 0; i < 4; ++i) b[size_t(60 + i)] = uint8_t(crc >> (8 * i));
        EXPECT_EQ(decode(b.data(), b.size(), out), DecodeStatus::BadTree);
    }
    {
        Asset a;
        a.grid = latticeGrid(4, 4, 4);
        a.header.flags = kFlagScatteredRadiance | kFlagTree;  // the flag, no nodes: encode writes an empty TREE
        a.topology.hiddenWidths = {2};
        a.voxels = {{0, 1.0f}};
        a.weights.assign(a.topology.parameterCount(), 0.125f);
        const std::vector<uint8_t> b = encodeUnchecked(a);
        EXPECT_EQ(decode(b.data(), b.size(), out), DecodeStatus::BadTree);
    }
    // Too deep: a chain of 49 splits along x of a 64-voxel lattice (each split's lower child a leaf); 48 are fine.
    {
        const uint32_t wide[3] = {64, 1, 1};
        auto chain = [](uint32_t splits) {
            std::vector<TreeNode> nodes(1);
            uint32_t leaf = 0, at = 0;
            for (uint32_t i = 0; i < splits; ++i) {
                const uint32_t c = uint32_t(nodes.size());
                nodes.resize(nodes.size() + 2);
                nodes[at] = {0, i + 1, c};
                nodes[c] = {kTreeLeaf, 0, leaf++};
                at = c + 1;
            }
            nodes[at] = {kTreeLeaf, 0, leaf};
            return nodes;
        };
        uint32_t n = 0;
        EXPECT_FALSE(validateTree(wide, chain(49), n));
        EXPECT_TRUE(validateTree(wide, chain(48), n));
        EXPECT_EQ(n, 49u);
    }
    // VOXL indexes leaves: an index past the last leaf is refused.
    {
        const std::vector<TreeNode> small = test::randomTree(dims, 5, 1);
        Asset a;
        a.grid = latticeGrid(4, 4, 4);
        a.header.flags = kFlagScatteredRadiance | kFlagTree;
        a.topology.hiddenWidths = {2};
        a.tree = small;
        a.voxels = {{5, 1.0f}};
        a.weights.assign(a.topology.parameterCount(), 0.125f);
        std::vector<uint8_t> b = encodeUnchecked(a);  // a leaf past the last: invalid on purpose
        EXPECT_EQ(decode(b.data(), b.size(), out), DecodeStatus::BadVoxels);
        a.voxels = {{4, 1.0f}};
        b = encode(a);
        EXPECT_EQ(decode(b.data(), b.size(), out), DecodeStatus::Ok);
    }
}

// encodedSize() is what the baker's byte budget counts: it must be encode()'s size exactly.
TEST(Tree, EncodedSizeIsTheEncodersSize) {
    const Grid g = latticeGrid(8, 8, 8);
    for (uint32_t leaves : {1u, 7u, 40u}) {
        for (auto enc : {WeightEncoding::Float16, WeightEncoding::Float32})
            for (size_t meta : {size_t(0), size_t(1), size_t(13)}) {
                Asset a;
                a.grid = g;
                a.header.flags = kFlagScatteredRadiance | (leaves > 1 ? kFlagTree : 0u);
                a.topology.hiddenWidths = leaves == 7 ? std::vector<uint32_t>{5, 3} : std::vector<uint32_t>{9};
                a.topology.weightEncoding = enc;
                if (leaves > 1) a.tree = test::randomTree(g.dims, leaves, leaves);
                for (uint32_t i = 0; i < leaves; ++i) a.voxels.push_back({i, 1.0f});
                a.weights.assign(a.voxels.size() * a.topology.parameterCount(), 0.5f);
                a.metadata = std::string(meta, 'x');
                EXPECT_EQ(encode(a).size(), encodedSize(a.topology, a.voxels.size(), a.tree.size(), meta)) << leaves << " " << meta;
            }
    }
}

}  // namespace
}  // namespace nrad::format
