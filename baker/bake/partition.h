// The adaptive partition (issue 15): a kd-tree over a fine lattice of the scene's box, refined greedily by
// the expected error reduction per byte until the asset's byte budget is spent. First by the residual: a
// cell's expected error is what a smooth model cannot explain of what its network must learn, the residual
// sum of squares of a least-squares fit, linear in position, normal and direction, of log(0.1 + the
// demodulated luminance) over the cell's training samples (a difference of that log is the relative error
// with relMSE's floor, so dark and bright cells weigh as in the validation's relMSE); a split's gain is the
// parent's residual minus its children's, at the best of seven planes per axis. Then, with a scorer, by the
// measured error of each leaf's briefly trained network. A split costs one network (when both children hold
// surface) and two tree nodes. Cells never split where there is no surface (a child without samples gets no
// network) and keep at least minLeafSamples samples each.
#pragma once

#include <cstdint>
#include <functional>
#include <vector>

#include <nrad/format.h>

#include "baker/bake/training_samples.h"
#include "baker/scene/scene.h"

namespace nrad {

struct PartitionSettings {
    uint64_t budgetBytes = 0;  // 0: no tree, the uniform grid of BakeSettings::grid
    // The lattice: 2^levels voxels along the scene's longest axis, the others in proportion. 10 (the format's largest,
    // kMaxGridDim): where a plane can only fall on a coarser lattice, the leaf beside a 2 cm wall kept a strip of the
    // other room, and at 64 KB the doorway scene's dark floor along the wall came out a block 25% too bright (levels 7;
    // docs/results.md).
    uint32_t levels = 10;
    uint32_t minLeafSamples = 256;  // samples a leaf with surface keeps at least (of its own, inside it)
    // With a scorer (the baker's): the share of the budget's networks placed by the residual alone; the rest
    // goes, a quarter of the open leaves per round, to the leaves whose briefly trained networks err most.
    double residualShare = 0.5;
    bool measured = true;  // refine by measured network error after the residual share (else by the residual alone)
    uint32_t candidatePlanes = 7;  // per axis and cell, evenly spaced on the lattice
    // A split is a candidate only where it removes at least this much of the residual per sample of the cell
    // (0: any gain).
    double minGainPerSample = 0.0;
    double minResidualShare = 0.0;  // ... and at least this share of the cell's residual
    // > 0: the lattice is a uniform grid's cells each gridRefine lattice voxels wide, and the tree starts as
    // that grid (every cell is a leaf before any other split); refinement then adds at most maxExtraDepth levels
    // under a grid cell.
    uint32_t gridRefine = 0;
    uint32_t maxExtraDepth = format::kMaxTreeDepth;
    // > 0: a split made after the grid (gridRefine) whose plane has no sample of its cell within this many lattice
    // voxels is hard (format::TreeNode::hard): it lies in a gap between surfaces, a wall's inside, and no
    // blending band crosses it (a band there had shaded the dark room's floor along the wall with the lit room's
    // network: docs/design.md). 0: none.
    float hardGap = 0.0f;
    // Networks of the light in the volume per leaf (BakeSettings::volume: 1, 2 with its glossy response), counted in
    // the budget: every leaf may get them (each with free space does), so the budget pays for them per leaf, beside
    // the surfaces' networks.
    uint32_t volumeNetworks = 0;
};

// The lattice's dimensions for a box (each axis at least 1, at most format::kMaxGridDim).
glm::uvec3 latticeDims(const Bounds3& bounds, uint32_t levels);

struct PartitionLeafInfo {
    format::TreeBox box;
    uint32_t depth = 0;
    uint32_t samples = 0;  // of its own
    double residual = 0.0;  // of the linear fit over its samples
};

struct AdaptivePartition {
    std::vector<format::TreeNode> tree;  // format order (format::validateTree holds)
    uint32_t leafCount = 0;
    std::vector<PartitionLeafInfo> leaves;  // in leaf order
    std::vector<uint32_t> leafOfSample;  // per training sample: the leaf holding it
    uint32_t networks = 0;  // leaves with samples
    uint64_t bytes = 0;  // format::encodedSize of the tree, the networks and the reserved metadata (and a leaf's
                         // volume networks for every leaf: an upper bound, PartitionSettings::volumeNetworks)
    double rootResidual = 0.0, residual = 0.0;  // summed over leaves, before and after refining
    uint64_t splitsSkippedForBudget = 0;
};

// What the metadata may take: `fixed` bytes plus perNetwork per network (the held-out error list).
struct MetadataReserve {
    uint64_t fixed = 0, perNetwork = 0;
    uint64_t bytes(uint64_t networks) const { return fixed + perNetwork * networks; }
};

// Measures cells by their networks (the baker trains one briefly per cell): for cells `ids` (stable
// identifiers, for seeding) with their sample indices, the error each would leave (held-out relMSE x samples).
using LeafScorer = std::function<std::vector<double>(const std::vector<uint32_t>& ids,
                                                     const std::vector<const std::vector<uint32_t>*>& samples)>;

// Refines the lattice `lattice` (a VoxelGrid's grid) for `samples` (their radiance as trained: `learned` gives
// each sample's value log(0.1 + demodulated luminance)) until no split fits the budget or gains anything.
// Throws std::runtime_error when even one network does not fit (the message names the smallest budget).
AdaptivePartition refinePartition(const format::Grid& lattice, const std::vector<TrainingSample>& samples,
                                  const std::vector<float>& learned, const format::Topology& topology,
                                  const PartitionSettings& settings, const MetadataReserve& reserve,
                                  const LeafScorer& scorer = {}, const std::function<void(double)>& progress = {});

// Walls inside the cells of a uniform grid (issue 38): where one voxel holds both sides of a thin wall (a lit
// room's floor beside a dark room's, 2 cm apart), its network must learn a step in position it cannot
// represent, and the lit side's light leaks across as a bright band with a false tint. The grid's cells are
// split, on a lattice wallRefine() times finer (every plane of it a candidate), at the axis-aligned planes that
// remove at least minGainPerSample of the residual of the cell's linear fit (refinePartition's) per sample and
// at least minResidualShare of it: a step between two sides (0.04 per sample is a step of 0.4 in log luminance
// where a tenth of the samples lie beyond it), not a gradient, which the fit explains. At most
// maxSplitsPerCell levels under a grid cell, each side keeping minSideSamples.
struct WallSplitSettings {
    bool enabled = true;
    double minGainPerSample = 0.04;  // residual of log(0.1 + luminance) removed per sample
    double minResidualShare = 0.3;  // ... and this share of the cell's residual at least
    uint32_t maxSplitsPerCell = 2;  // tree levels under a grid cell
    uint32_t minSideSamples = 256;
    // PartitionSettings::hardGap of the splits at walls, in lattice voxels (wallRefine's: 1/256 of a grid cell).
    float hardGap = 0.5f;
};
// The lattice refinement for a grid: the largest power of two (at most 256) keeping every axis within kMaxGridDim.
uint32_t wallRefine(const format::Grid& grid);
// The grid `grid` as a tree on a lattice wallRefine(grid) times finer, its cells split at walls. The result has
// leafCount == the grid's voxel count when no wall was found (then the plain grid is the same partition).
AdaptivePartition splitWalls(const format::Grid& grid, const std::vector<TrainingSample>& samples, const std::vector<float>& learned,
                             const WallSplitSettings& settings);

}  // namespace nrad
