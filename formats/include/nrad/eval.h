// The evaluation contract of an .nrad asset, defined once: how a point finds its network, how the nine
// inputs are encoded, how a network's outputs become radiance, and how that radiance is recombined with the
// surface's material when shading. The baker (training targets, inputs, the decoded prediction it judges)
// and the runtime's scalar path call these functions; the SIMD kernels compute the same arithmetic in
// vector registers and are tested against vectors generated from here (tests/runtime). docs/format.md
// specifies it in words. Only the C++17 standard library.
#pragma once

#include <cmath>
#include <cstdint>
#include <cstring>
#include <vector>

#include "nrad/eval_constants.h"
#include "nrad/format.h"

namespace nrad::eval {

// ----- how a point finds its network -----------------------------------------------------------------------

// dims / (upper - lower) along one axis: the factor of the continuous grid coordinate (computed once per
// grid; every user multiplies by this very float, so the voxel rule and the position input always agree).
inline float gridFactor(const format::Grid& g, int axis) { return float(g.dims[axis]) / (g.upper[axis] - g.lower[axis]); }

// Continuous grid coordinate of p along one axis: (p - lower) x factor.
inline float gridCoordinate(float p, float lower, float factor) { return (p - lower) * factor; }

// Voxel coordinate from the continuous one: floor(t), with the upper face belonging to the last voxel. A point
// on an interior border belongs to the voxel above it.
inline int voxelCoordinate(float t, uint32_t dim) {
    int i = int(t);
    return i >= int(dim) ? int(dim) - 1 : (i < 0 ? 0 : i);
}

// Where a point is: its voxel (linear index x + dims[0] (y + dims[1] z)) and its position inside that voxel
// mapped to [-1, 1]^3 (the network's first three inputs: 2 (t - coord) - 1, clamped to [-1, 1]).
struct Location {
    int64_t voxel = -1;  // -1: outside the grid [lower, upper] (or not finite)
    int coord[3] = {0, 0, 0};
    float local[3] = {0, 0, 0};
};

// Position of p relative to voxel `coord`, in the voxel's [-1, 1]^3 frame (not clamped: beyond +-1 outside
// that voxel).
inline float localCoordinate(float p, float lower, float factor, int coord) {
    return 2.0f * (gridCoordinate(p, lower, factor) - float(coord)) - 1.0f;
}

inline float clampUnit(float q) { return q < -1.0f ? -1.0f : (q > 1.0f ? 1.0f : q); }

// `factor` holds gridFactor for the three axes.
inline Location locate(const format::Grid& g, const float factor[3], const float p[3]) {
    Location r;
    for (int k = 0; k < 3; ++k) {
        if (!(p[k] >= g.lower[k] && p[k] <= g.upper[k])) return r;
        r.coord[k] = voxelCoordinate(gridCoordinate(p[k], g.lower[k], factor[k]), g.dims[k]);
        r.local[k] = clampUnit(localCoordinate(p[k], g.lower[k], factor[k], r.coord[k]));
    }
    r.voxel = int64_t(r.coord[0]) + int64_t(g.dims[0]) * (int64_t(r.coord[1]) + int64_t(g.dims[1]) * int64_t(r.coord[2]));
    return r;
}

inline Location locate(const format::Grid& g, const float p[3]) {
    const float factor[3] = {gridFactor(g, 0), gridFactor(g, 1), gridFactor(g, 2)};
    return locate(g, factor, p);
}

// ----- blended supports: how a point finds its networks and their weights ---------------------------------

// With kFlagBlended, a point within `band` voxels of an interior face is shaded by the networks on both
// sides, weighted by a partition of unity that depends only on the point's grid coordinate t: the voxel above
// the face at integer k weighs s((t - k + band) / (2 band)), the one below 1 minus that, with s the smoothstep
// 3u^2 - 2u^3 (u clamped to [0, 1]). Both sides compute the same t - k, so the shaded result is continuous
// across every face; s is C1, so it has no kink either. Faces on the grid's boundary have no neighbour. In 3D
// the weights are the products of the three axes' (up to 2 x 2 x 2 = 8 networks at a corner, 1 in the
// interior), a support's position input is p relative to its own voxel (beyond [-1, 1] by up to 2 band;
// networks train on their voxel plus that margin), and supports whose voxel has no network are dropped
// and the rest renormalised (keepOccupied).
constexpr int kMaxSupports = 8;

// No default member values: arrays of them are declared per point on hot paths, and supports() writes every
// field of the entries it returns.
struct Support {
    int64_t voxel;  // linear index (the voxel's, or the tree leaf's)
    float weight;
    float local[3];  // position input relative to this voxel
};

// Weight of the voxel above a face for a point at grid coordinate distance x = t - k from it.
inline float aboveFaceWeight(float x, float band) {
    float u = (x + band) / (2.0f * band);
    u = u < 0.0f ? 0.0f : (u > 1.0f ? 1.0f : u);
    return u * u * (3.0f - 2.0f * u);
}

// Whether a point at voxel coordinate c (fraction f = t - c) of an axis with dim voxels is in the band of
// its lower (-1) or upper (+1) interior face, or in neither (0). The SIMD kernels test exactly this for their
// single-network fast path.
inline int bandSide(int c, float f, uint32_t dim, float band) {
    if (c > 0 && f < band) return -1;
    if (c + 1 < int(dim) && f > 1.0f - band) return 1;
    return 0;
}

// Every network support of p, in increasing voxel order (z, then y, then x, lower first), with weights that
// sum to 1 up to rounding (before keepOccupied). Returns their count: 0 outside the grid (or for a non-finite p),
// 1 with weight 1 and the position clamped to [-1, 1] when band is 0 or p lies in no band (exactly locate()).
inline int supports(const format::Grid& g, const float factor[3], float band, const float p[3], Support out[kMaxSupports]) {
    int coord[3][2];
    float weight[3][2];
    int n[3];
    for (int k = 0; k < 3; ++k) {
        if (!(p[k] >= g.lower[k] && p[k] <= g.upper[k])) return 0;
        const float t = gridCoordinate(p[k], g.lower[k], factor[k]);
        const int c = voxelCoordinate(t, g.dims[k]);
        const int side = band > 0.0f ? bandSide(c, t - float(c), g.dims[k], band) : 0;
        if (side == 0) {
            n[k] = 1;
            coord[k][0] = c;
            weight[k][0] = 1.0f;
            continue;
        }
        const int below = side < 0 ? c - 1 : c;  // the face lies between voxels below and below + 1
        const float above = aboveFaceWeight(t - float(below + 1), band);
        n[k] = 2;
        coord[k][0] = below;
        coord[k][1] = below + 1;
        weight[k][0] = 1.0f - above;
        weight[k][1] = above;
    }
    int count = 0;
    for (int z = 0; z < n[2]; ++z)
        for (int y = 0; y < n[1]; ++y)
            for (int x = 0; x < n[0]; ++x) {
                Support& s = out[count++];
                const int c[3] = {coord[0][x], coord[1][y], coord[2][z]};
                s.voxel = int64_t(c[0]) + int64_t(g.dims[0]) * (int64_t(c[1]) + int64_t(g.dims[1]) * int64_t(c[2]));
                s.weight = weight[0][x] * weight[1][y] * weight[2][z];
                for (int k = 0; k < 3; ++k) {
                    const float reach = n[k] == 1 ? 1.0f : 1.0f + 2.0f * band;  // [-1, 1] on an axis without a band
                    const float q = localCoordinate(p[k], g.lower[k], factor[k], c[k]);
                    s.local[k] = q < -reach ? -reach : (q > reach ? reach : q);
                }
            }
    return count;
}

// Drops the supports whose voxel has no network (occupied(voxel) false) or whose weight rounded to 0, and
// divides the others' weights by their sum (summed in order; done even when none was dropped, so every caller
// rounds alike). Returns how many remain (0: the point is in an empty voxel and every neighbour it blends with is empty too).
template <class Occupied>
inline int keepOccupied(Support* s, int count, Occupied&& occupied) {
    int kept = 0;
    float sum = 0.0f;
    for (int i = 0; i < count; ++i)
        if (s[i].weight > 0.0f && occupied(s[i].voxel)) {
            s[kept++] = s[i];
            sum += s[kept - 1].weight;
        }
    for (int i = 0; i < kept; ++i) s[i].weight = s[i].weight / sum;
    return kept;
}

// The blended radiance is the sum over the kept supports, in their order, of weight x decoded radiance.

// ----- the kd-tree partition (format::kFlagTree) ------------------------------------------------------------

// A point's leaf: descend from the root, taking the upper child where the grid coordinate t >= split (a point
// on a plane belongs to the cell above it, as with voxels). Blending at a node's plane uses the half-width
// band x (the smallest extent, along the node's axis, of the leaves below the node that touch the plane; 0 at a
// hard node's plane, format::TreeNode::hard), in
// lattice voxels: every leaf's bands are at most band x its own extent, so (band <= 1/2) the bands of a leaf's
// opposite faces never overlap and its position input stays within 1 + 2 band, as on the grid. Where a point
// lies within a node's half-width w of its plane (|t - split| < w) both children shade it, the upper one
// weighted aboveFaceWeight(t - split, w) and the lower one 1 minus that, and a leaf's weight is the product of
// those factors along its path (per axis, then x y z, as on the grid): the weights of every leaf sum to 1 at
// every point and are C1 across every plane, whatever the leaves' sizes. For the uniform tree
// (format::uniformTree) every extent is 1, so each node's width is the grid's band and each point's supports,
// weights and position inputs are the grid's, bit for bit.
inline std::vector<float> treeBandWidths(const uint32_t dims[3], const std::vector<format::TreeNode>& nodes, float band) {
    std::vector<float> width(nodes.size(), 0.0f);
    if (!(band > 0.0f) || nodes.empty()) return width;
    std::vector<uint32_t> smallest(nodes.size(), UINT32_MAX);
    std::vector<uint32_t> path;
    struct Walk {
        const std::vector<format::TreeNode>& nodes;
        std::vector<uint32_t>& smallest;
        std::vector<uint32_t>& path;
        void operator()(uint32_t at, format::TreeBox b) {
            const format::TreeNode& n = nodes[at];
            if (n.axis == format::kTreeLeaf) {
                for (uint32_t a : path) {
                    const format::TreeNode& up = nodes[a];
                    const uint32_t extent = b.hi[up.axis] - b.lo[up.axis];
                    if ((b.lo[up.axis] == up.split || b.hi[up.axis] == up.split) && extent < smallest[a]) smallest[a] = extent;
                }
                return;
            }
            path.push_back(at);
            format::TreeBox lower = b, upper = b;
            lower.hi[n.axis] = n.split;
            upper.lo[n.axis] = n.split;
            (*this)(n.child, lower);
            (*this)(n.child + 1, upper);
            path.pop_back();
        }
    };
    format::TreeBox root;
    for (int k = 0; k < 3; ++k) root.hi[k] = dims[k];
    Walk{nodes, smallest, path}(0, root);
    for (size_t i = 0; i < nodes.size(); ++i)
        if (nodes[i].axis != format::kTreeLeaf && !nodes[i].hard) width[i] = band * float(smallest[i]);
    return width;
}

// The leaf holding lattice coordinate t (no blending: the planes alone), narrowing `box` (given as the
// lattice's) to the leaf's.
inline uint32_t treeLeafAt(const format::TreeNode* nodes, const float t[3], format::TreeBox& box) {
    uint32_t at = 0;
    while (nodes[at].axis != format::kTreeLeaf) {
        const format::TreeNode& n = nodes[at];
        if (t[n.axis] >= float(n.split)) {
            box.lo[n.axis] = n.split;
            at = n.child + 1;
        } else {
            box.hi[n.axis] = n.split;
            at = n.child;
        }
    }
    return nodes[at].child;
}

// The leaf holding p (no blending) and its lattice box; -1 outside the grid (or for a non-finite p).
inline int64_t treeLeaf(const format::Grid& g, const float factor[3], const format::TreeNode* nodes, const float p[3],
                        format::TreeBox* box = nullptr) {
    float t[3];
    format::TreeBox b;
    for (int k = 0; k < 3; ++k) {
        if (!(p[k] >= g.lower[k] && p[k] <= g.upper[k])) return -1;
        t[k] = gridCoordinate(p[k], g.lower[k], factor[k]);
        b.hi[k] = g.dims[k];
    }
    const uint32_t leaf = treeLeafAt(nodes, t, b);
    if (box) *box = b;
    return leaf;
}

// Position input of grid coordinate t relative to the lattice interval [lo, hi) (2 (t - lo) / (hi - lo) - 1).
inline float localInBox(float t, uint32_t lo, uint32_t hi) { return 2.0f * (t - float(lo)) / float(hi - lo) - 1.0f; }

// An acceleration of the descent (not part of the contract: results are identical with or without it): a
// coarse table over the lattice that gives, for each of its cells, the deepest node whose box holds the whole
// cell and none of whose ancestors' planes blends anywhere in it (with a margin of 1e-3 voxels against
// rounding). Every point of the cell starts there with weights 1, which is what the descent from the root
// reaches too.
inline std::vector<uint32_t> buildTreeStarts(const uint32_t dims[3], const std::vector<format::TreeNode>& nodes,
                                             const std::vector<float>& widths, const uint32_t startDims[3]) {
    std::vector<uint32_t> starts(size_t(startDims[0]) * startDims[1] * startDims[2]);
    constexpr float kMargin = 1e-3f;
    for (uint32_t z = 0; z < startDims[2]; ++z)
        for (uint32_t y = 0; y < startDims[1]; ++y)
            for (uint32_t x = 0; x < startDims[0]; ++x) {
                const uint32_t c[3] = {x, y, z};
                float lo[3], hi[3];
                for (int k = 0; k < 3; ++k) {
                    lo[k] = float(c[k]) * float(dims[k]) / float(startDims[k]) - kMargin;
                    hi[k] = float(c[k] + 1) * float(dims[k]) / float(startDims[k]) + kMargin;
                }
                uint32_t at = 0;
                while (nodes[at].axis != format::kTreeLeaf) {
                    const format::TreeNode& n = nodes[at];
                    const float split = float(n.split), w = widths[at];
                    if (hi[n.axis] <= split - w)
                        at = n.child;
                    else if (lo[n.axis] >= split + w)
                        at = n.child + 1;
                    else
                        break;
                }
                starts[(size_t(z) * startDims[1] + y) * startDims[0] + x] = at;
            }
    return starts;
}

struct TreeView {
    const format::TreeNode* nodes = nullptr;
    const float* widths = nullptr;  // treeBandWidths
    const format::TreeBox* boxes = nullptr;  // per leaf (format::validateTree)
    const uint32_t* starts = nullptr;  // optional: buildTreeStarts
    uint32_t startDims[3] = {0, 0, 0};
    float startScale[3] = {0, 0, 0};  // start-table cells per lattice voxel
};

// Every leaf that shades p, in leaf order (depth first, lower first), with its weight and p's position input
// relative to it: the tree's supports() (keepOccupied applies the same way, with leaf indices). Widths from
// treeBandWidths (band 0: all zero, one support). At most kMaxSupports (a validated tree with
// treeBandWidths' widths has no more).
inline int treeSupports(const format::Grid& g, const float factor[3], const TreeView& v, float band, const float p[3],
                        Support out[kMaxSupports]) {
    float t[3];
    for (int k = 0; k < 3; ++k) {
        if (!(p[k] >= g.lower[k] && p[k] <= g.upper[k])) return 0;
        t[k] = gridCoordinate(p[k], g.lower[k], factor[k]);
    }
    // The descent keeps the current node and weights in registers; a node whose plane blends the point
    // continues into its lower child and leaves the upper one on the stack (taken after the lower subtree:
    // leaf order).
    struct Item {
        uint32_t node;
        float w[3];
    };
    Item stack[format::kMaxTreeDepth + 2];
    int top = 0;
    uint32_t node = 0;
    if (v.starts) {
        size_t at = 0;
        for (int k = 2; k >= 0; --k) {
            const int c = int(t[k] * v.startScale[k]);
            at = at * v.startDims[k] + size_t(c < 0 ? 0 : (c >= int(v.startDims[k]) ? int(v.startDims[k]) - 1 : c));
        }
        node = v.starts[at];
    }
    float w0 = 1.0f, w1 = 1.0f, w2 = 1.0f;
    bool blended[3] = {false, false, false};
    int count = 0;
    for (;;) {
        for (;;) {
            const format::TreeNode n = v.nodes[node];
            if (n.axis == format::kTreeLeaf) break;
            const int k = int(n.axis);
            const float x = t[k] - float(n.split), w = v.widths[node];
            if (w > 0.0f && x > -w && x < w) {
                const float above = aboveFaceWeight(x, w);
                blended[k] = true;
                Item& up = stack[top++];
                up.node = n.child + 1;
                up.w[0] = w0;
                up.w[1] = w1;
                up.w[2] = w2;
                up.w[k] = up.w[k] * above;
                float& wk = k == 0 ? w0 : (k == 1 ? w1 : w2);
                wk = wk * (1.0f - above);
                node = n.child;
            } else {
                node = x >= 0.0f ? n.child + 1 : n.child;
            }
        }
        NRAD_CHECK(count < kMaxSupports);  // (a validated tree's band reaches at most 2 x 2 x 2 leaves)
        out[count].voxel = int64_t(v.nodes[node].child);
        out[count++].weight = w0 * w1 * w2;
        if (top == 0) break;
        const Item& it = stack[--top];
        node = it.node;
        w0 = it.w[0];
        w1 = it.w[1];
        w2 = it.w[2];
    }
    for (int i = 0; i < count; ++i) {
        const format::TreeBox& b = v.boxes[size_t(out[i].voxel)];
        for (int k = 0; k < 3; ++k) {
            const float reach = blended[k] ? 1.0f + 2.0f * band : 1.0f;
            const float q = localInBox(t[k], b.lo[k], b.hi[k]);
            out[i].local[k] = q < -reach ? -reach : (q > reach ? reach : q);
        }
    }
    return count;
}

// How an asset's points find their networks, whichever partition it has: what the runtime and the baker hold.
struct Partition {
    format::Grid grid;
    float factor[3] = {1.0f, 1.0f, 1.0f};  // gridFactor per axis
    float band = 0.0f;  // the blending band (kFlagBlended), else 0
    std::vector<format::TreeNode> tree;  // empty: the uniform grid
    std::vector<float> widths;  // treeBandWidths
    std::vector<format::TreeBox> boxes;  // per leaf
    std::vector<uint32_t> starts;  // buildTreeStarts, with at most kMaxStartCells per axis
    uint32_t startDims[3] = {0, 0, 0};
    float startScale[3] = {0, 0, 0};
    uint64_t cells = 0;  // voxels or leaves
    static constexpr uint32_t kMaxStartCells = 32;

    Partition() = default;
    // `nodes` must be a valid tree over g.dims (format::validateTree), or empty for the grid.
    Partition(const format::Grid& g, float blendBand, std::vector<format::TreeNode> nodes, uint32_t leafCount, bool accelerate = true)
        : grid(g), band(blendBand), tree(std::move(nodes)) {
        for (int k = 0; k < 3; ++k) factor[k] = gridFactor(g, k);
        cells = tree.empty() ? g.voxelCount() : uint64_t(leafCount);
        if (tree.empty()) return;
        uint32_t leaves = 0;
        const bool valid = format::validateTree(g.dims, tree, leaves, &boxes);
        NRAD_CHECK(valid && leaves == leafCount);  // (the decoder validates an asset's tree; a bake's is built valid)
        widths = treeBandWidths(g.dims, tree, band);
        if (!accelerate) return;
        for (int k = 0; k < 3; ++k) {
            startDims[k] = g.dims[k] < kMaxStartCells ? g.dims[k] : kMaxStartCells;
            startScale[k] = float(startDims[k]) / float(g.dims[k]);
        }
        starts = buildTreeStarts(g.dims, tree, widths, startDims);
    }
    explicit Partition(const format::Asset& a, bool accelerate = true)
        : Partition(a.grid, (a.header.flags & format::kFlagBlended) ? a.grid.blendBand : 0.0f, a.tree, a.leafCount, accelerate) {}

    TreeView view() const {
        TreeView v;
        v.nodes = tree.data();
        v.widths = widths.data();
        v.boxes = boxes.data();
        if (!starts.empty()) {
            v.starts = starts.data();
            for (int k = 0; k < 3; ++k) {
                v.startDims[k] = startDims[k];
                v.startScale[k] = startScale[k];
            }
        }
        return v;
    }
    int supports(const float p[3], Support out[kMaxSupports]) const {
        return tree.empty() ? eval::supports(grid, factor, band, p, out) : treeSupports(grid, factor, view(), band, p, out);
    }
    // The cell holding p without blending, -1 outside.
    int64_t cellOf(const float p[3]) const {
        if (!tree.empty()) return treeLeaf(grid, factor, tree.data(), p);
        return locate(grid, factor, p).voxel;
    }
    // Memory held, in bytes.
    size_t bytes() const {
        return tree.size() * (sizeof(format::TreeNode) + sizeof(float)) + boxes.size() * sizeof(format::TreeBox) +
               starts.size() * sizeof(uint32_t);
    }
};

// ----- inputs ------------------------------------------------------------------------------------------------

// x = (position in the voxel, shading normal, direction towards the viewer), normal and direction unit
// length in world space.
inline void encodeInputs(const float local[3], const float normal[3], const float direction[3], float x[kInputs]) {
    for (int k = 0; k < 3; ++k) {
        x[k] = local[k];
        x[3 + k] = normal[k];
        x[6 + k] = direction[k];
    }
}

// ----- the network --------------------------------------------------------------------------------------------

// The plain forward pass of one network in the format's parameter order (per layer W, out x in row-major,
// then b): ReLU hidden layers, a linear last layer, in float, each sum from the bias up in input order.
constexpr uint32_t kForwardScratch = 2 * format::kMaxHiddenWidth;  // floats of scratch forward() needs
inline void forward(uint32_t hiddenLayers, const uint32_t* hiddenWidths, const float* params, const float x[kInputs],
                    float y[kOutputs], float* scratch) {
    float* a = scratch;
    float* b = scratch + format::kMaxHiddenWidth;
    uint32_t in = uint32_t(kInputs);
    for (int i = 0; i < kInputs; ++i) a[i] = x[i];
    const float* w = params;
    for (uint32_t l = 0; l <= hiddenLayers; ++l) {
        bool last = l == hiddenLayers;
        uint32_t out = last ? uint32_t(kOutputs) : hiddenWidths[l];
        const float* bias = w + size_t(out) * in;
        for (uint32_t o = 0; o < out; ++o) {
            float s = bias[o];
            for (uint32_t i = 0; i < in; ++i) s += w[size_t(o) * in + i] * a[i];
            b[o] = last || s > 0.0f ? s : 0.0f;
        }
        for (uint32_t o = 0; o < out; ++o) a[o] = b[o];
        w = bias + out;
        in = out;
    }
    for (int c = 0; c < kOutputs; ++c) y[c] = a[c];
}

inline void forward(const format::Topology& t, const float* params, const float x[kInputs], float y[kOutputs], float* scratch) {
    forward(uint32_t(t.hiddenWidths.size()), t.hiddenWidths.data(), params, x, y, scratch);
}

// ----- outputs --------------------------------------------------------------------------------------------------

// exp(y) - 1 (constants in nrad/eval_constants.h). The SIMD kernels compute the same steps (and the layers)
// with fused multiply-adds, their own order of sums and round-to-nearest-even for n, which changes the last
// bits (tests/runtime holds them to 1e-5 of max(1, value) against this file).
inline float expMinusOne(float v) {
    if (v != v) return v;  // NaN (a network overflowed on huge inputs): stays NaN, decodeOutput maps it to 0
    float xe = v < kMinLog ? kMinLog : (v > kMaxLog ? kMaxLog : v);
    float n = float(int(xe * kLog2e + (xe >= 0.0f ? 0.5f : -0.5f)));
    float r = (xe - n * kLn2Hi) - n * kLn2Lo;
    float q = kExpP[6];
    for (int k = 5; k >= 0; --k) q = q * r + kExpP[k];
    int bits = (int(n) + 127) << 23;  // 2^n from its exponent bits
    float pow2;
    std::memcpy(&pow2, &bits, 4);
    return q * pow2 - 1.0f;
}

// 2^x for the shading contract (the reflectance fit's exp2(-9.28 n.wo)), defined here instead of taken from
// the C library so that every kernel, vector or not, and the GPU compute the same value (the library's exp2f
// differs between its own CPU variants): x clamped to [-kMaxExp2, kMaxExp2] (NaN to the lower end), x = n + f
// with n rounded half away from zero, 2^f = exp(f ln2) by kExpP's polynomial, times 2^n from its exponent bits.
// Relative error below 3e-7.
inline float exp2Poly(float x) {
    const float xc = !(x > -kMaxExp2) ? -kMaxExp2 : (x > kMaxExp2 ? kMaxExp2 : x);
    const float n = float(int(xc + (xc >= 0.0f ? 0.5f : -0.5f)));
    const float r = (xc - n) * kLn2;
    float q = kExpP[6];
    for (int k = 5; k >= 0; --k) q = q * r + kExpP[k];
    int bits = (int(n) + 127) << 23;
    float pow2;
    std::memcpy(&pow2, &bits, 4);
    return q * pow2;
}

// Radiance from one output value: transform, the voxel's scale, clamped to [0, kMaxRadiance] (NaN becomes 0).
inline float decodeOutput(format::OutputTransform transform, float scale, float y) {
    float v = transform == format::OutputTransform::Exponential ? expMinusOne(y) : y;
    v *= scale;
    v = v > 0.0f ? v : 0.0f;
    return v < kMaxRadiance ? v : kMaxRadiance;
}

inline void decodeOutputs(format::OutputTransform transform, float scale, const float y[kOutputs], float rgb[kOutputs]) {
    for (int c = 0; c < kOutputs; ++c) rgb[c] = decodeOutput(transform, scale, y[c]);
}

// ----- shading: what the networks store, and how it is recombined with the material ------------------------------

// ----- the light in the volume (format 2.4, VVOX/VWGT) ---------------------------------------------------------

// The volume query: for a point x anywhere in the grid and a unit normal n, the radiance a white Lambertian
// receiver at x facing n scatters, E(x, n) / pi. The surfaces' contract read with the volume's cells and networks:
// supports()/treeSupports() and keepOccupied() over the cells with a volume network, encodeInputs(local, n, n)
// (the normal in the direction slot too), forward(), decodeOutputs() with the cell's VVOX scale and the volume's
// transform (format::Asset::volumeTransform(): exponential with format 2.6's kFlagVolumeExponential), the weighted
// sum; never multiplied by a reflectance, never with an emission added. A diffuse receiver of albedo a reflects a
// times it.

// The material terms a shader has at a pixel (an engine's G-buffer): base colour (textures applied, linear),
// metallic, roughness (perceptual), the KHR_materials_specular factor (1 where the material has none) and
// the emitted radiance towards the viewer.
struct Surface {
    float baseColor[3] = {1.0f, 1.0f, 1.0f};
    float metallic = 0.0f;
    float roughness = 1.0f;
    float specular = 1.0f;
    float emission[3] = {0.0f, 0.0f, 0.0f};
};

// Karis's split-sum terms (A, B) for roughness `rough` in [0, 1] and n.wo (clamped to [0, 1] here).
inline void splitSumTerms(float rough, float cosNV, float& A, float& B) {
    const float c0[4] = {-1.0f, -0.0275f, -0.572f, 0.022f}, c1[4] = {1.0f, 0.0425f, 1.04f, -0.04f};
    const float nv = cosNV > 0.0f ? (cosNV < 1.0f ? cosNV : 1.0f) : 0.0f;
    float r[4];
    for (int i = 0; i < 4; ++i) r[i] = rough * c0[i] + c1[i];
    const float a004 = std::fmin(r[0] * r[0], exp2Poly(-9.28f * nv)) * r[0] + r[1];
    A = std::fmax(0.0f, -1.04f * a004 + r[2]);
    B = std::fmax(0.0f, 1.04f * a004 + r[3]);
}

// The reflectance an asset with format::kFlagDemodulated divides by: the diffuse albedo
// baseColor (1 - metallic) plus the specular lobe's directional albedo F0 A + w B for the viewing angle,
// with F0 = 0.04 specular (1 - metallic) + baseColor metallic, w = specular (1 - metallic) + metallic, and
// (A, B) Karis's fit of the GGX split-sum terms over roughness and n.wo ("Physically Based Shading on
// Mobile", 2014). A demodulation factor both sides agree on, not the BSDF's exact albedo; about 0 to 1.1.
inline void reflectance(const Surface& s, float cosNV, float out[3]) {
    const float rough = s.roughness < 0.0f ? 0.0f : (s.roughness > 1.0f ? 1.0f : s.roughness);
    const float m = s.metallic < 0.0f ? 0.0f : (s.metallic > 1.0f ? 1.0f : s.metallic);
    float A, B;
    splitSumTerms(rough, cosNV, A, B);
    const float w = s.specular * (1.0f - m) + m;
    for (int c = 0; c < 3; ++c) {
        const float base = s.baseColor[c] > 0.0f ? (s.baseColor[c] < 1.0f ? s.baseColor[c] : 1.0f) : 0.0f;
        const float f0 = 0.04f * s.specular * (1.0f - m) + base * m;
        out[c] = base * (1.0f - m) + f0 * A + w * B;
        if (!(out[c] > 0.0f)) out[c] = 0.0f;  // NaN too
    }
}

// Training divides by the reflectance floored at this (a black channel has nothing to learn; its loss weight
// is (R / floored R)^2, so it is left free), shading multiplies by the reflectance itself.
constexpr float kMinReflectance = 0.02f;

// The radiance leaving a surface point towards the viewer, from what the asset returns there, the surface's
// material and the cosine between its shading normal and the direction towards the viewer:
//   flags 0:                           L = asset
//   kFlagScatteredRadiance:            L = asset + Le
//   kFlagScatteredRadiance | Demod.:   L = R(material, n.wo) asset + Le
inline void shade(uint32_t contentFlags, const float assetRadiance[3], const Surface& surface, float cosNV, float out[3]) {
    const bool scattered = (contentFlags & format::kFlagScatteredRadiance) != 0;
    float r[3] = {1.0f, 1.0f, 1.0f};
    if (contentFlags & format::kFlagDemodulated) reflectance(surface, cosNV, r);
    for (int c = 0; c < 3; ++c) out[c] = r[c] * assetRadiance[c] + (scattered ? surface.emission[c] : 0.0f);
}

// A receiver that was not in the bake (a moving object; issue 42), shaded from the asset's volume query:
// volumeRadiance is D(x, n) = E(x, n) / pi at the receiver's point and shading normal (what a white Lambertian
// receiver there scatters). The receiver reflects it times its reflectance() (its diffuse albedo plus the
// specular lobe's directional albedo: exact for a Lambertian receiver; a glossy lobe is taken to see the
// cosine-weighted mean of the light arriving), plus its own emission towards the viewer.
inline void shadeVolume(const float volumeRadiance[3], const Surface& surface, float cosNV, float out[3]) {
    float r[3];
    reflectance(surface, cosNV, r);
    for (int c = 0; c < 3; ++c) out[c] = r[c] * volumeRadiance[c] + surface.emission[c];
}

// ----- the volume's glossy response (format 2.5, VGLX/VGLW) ---------------------------------------------------

// The glossy query: for x, a unit normal n and the unit direction v towards the viewer, the radiance a GGX receiver
// of roughness kGlossyRoughness (perceptual), white and metallic (Fresnel 1), at x facing n reflects towards v,
// divided by glossyAlbedo(n.v): the light arriving at x prefiltered by that lobe. The volume query's contract with
// the glossy cells and networks and encodeInputs(local, n, v).
constexpr float kGlossyRoughness = 0.3f;

// What the glossy response is divided by: the split-sum albedo of the lobe (F0 = 1, so A + B) at n.v.
inline float glossyAlbedo(float cosNV) {
    float A, B;
    splitSumTerms(kGlossyRoughness, cosNV, A, B);
    return A + B;
}

// A receiver that was not in the bake shaded from both volume queries: its diffuse albedo baseColor (1 - metallic)
// times D = E / pi, plus its specular lobe's split-sum albedo (reflectance()'s F0 A + w B) times the prefiltered
// light P, plus its emission. P is the glossy response at roughness <= kGlossyRoughness (its lobe's light: exact
// at kGlossyRoughness, blurrier than a smoother lobe's), blended linearly in roughness to D at roughness 1 (where
// shadeVolume's rule, the cosine-weighted mean, takes over): at roughness 1 this is shadeVolume.
inline void shadeVolumeGlossy(const float volumeRadiance[3], const float glossyRadiance[3], const Surface& s, float cosNV,
                              float out[3]) {
    const float rough = s.roughness < 0.0f ? 0.0f : (s.roughness > 1.0f ? 1.0f : s.roughness);
    const float m = s.metallic < 0.0f ? 0.0f : (s.metallic > 1.0f ? 1.0f : s.metallic);
    float A, B;
    splitSumTerms(rough, cosNV, A, B);
    const float w = s.specular * (1.0f - m) + m;
    const float t = rough > kGlossyRoughness ? (rough - kGlossyRoughness) / (1.0f - kGlossyRoughness) : 0.0f;
    for (int c = 0; c < 3; ++c) {
        const float base = s.baseColor[c] > 0.0f ? (s.baseColor[c] < 1.0f ? s.baseColor[c] : 1.0f) : 0.0f;
        const float f0 = 0.04f * s.specular * (1.0f - m) + base * m;
        const float specular = std::fmax(0.0f, f0 * A + w * B);
        const float prefiltered = (1.0f - t) * glossyRadiance[c] + t * volumeRadiance[c];
        const float v = base * (1.0f - m) * volumeRadiance[c] + specular * prefiltered;
        out[c] = (v > 0.0f ? v : 0.0f) + s.emission[c];  // NaN to 0
    }
}


}  // namespace nrad::eval
