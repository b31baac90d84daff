// Greedy kd-tree refinement by expected error reduction per byte.
#include "baker/bake/partition.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <queue>
#include <stdexcept>
#include <string>

#include <nrad/eval.h>

namespace nrad {

glm::uvec3 latticeDims(const Bounds3& bounds, uint32_t levels) {
    const glm::vec3 e = bounds.upper - bounds.lower;
    const float longest = std::max({e.x, e.y, e.z, 1e-6f});
    const float finest = float(1u << std::min(levels, 10u));
    glm::uvec3 d;
    for (int k = 0; k < 3; ++k)
        d[k] = uint32_t(std::clamp(std::lround(double(e[k] / longest) * finest), 1l, long(format::kMaxGridDim)));
    return d;
}

namespace {

constexpr int kFeatures = 10;  // 1, position (3), normal (3), direction (3)
constexpr int kMoments = kFeatures * (kFeatures + 1) / 2;
constexpr size_t kMaxStatSamples = 8192;  // a split's statistics from at most this many of a cell's samples

// Sufficient statistics of a least-squares fit: sum f f^T (upper triangle), sum f y, sum y^2, count.
struct Moments {
    double m[kMoments] = {};
    double v[kFeatures] = {};
    double s = 0.0, n = 0.0;
    void add(const float f[kFeatures], float y) {
        int at = 0;
        for (int i = 0; i < kFeatures; ++i) {
            for (int j = i; j < kFeatures; ++j) m[at++] += double(f[i]) * double(f[j]);
            v[i] += double(f[i]) * double(y);
        }
        s += double(y) * double(y);
        n += 1.0;
    }
    Moments plus(const Moments& o) const {
        Moments r;
        for (int i = 0; i < kMoments; ++i) r.m[i] = m[i] + o.m[i];
        for (int i = 0; i < kFeatures; ++i) r.v[i] = v[i] + o.v[i];
        r.s = s + o.s;
        r.n = n + o.n;
        return r;
    }
    Moments minus(const Moments& o) const {
        Moments r;
        for (int i = 0; i < kMoments; ++i) r.m[i] = m[i] - o.m[i];
        for (int i = 0; i < kFeatures; ++i) r.v[i] = v[i] - o.v[i];
        r.s = s - o.s;
        r.n = n - o.n;
        return r;
    }
    // Residual sum of squares of the ridge-regularised fit (Cholesky of the 10 x 10 normal equations).
    double residual() const {
        if (n < 1.0) return 0.0;
        double a[kFeatures][kFeatures];
        int at = 0;
        for (int i = 0; i < kFeatures; ++i)
            for (int j = i; j < kFeatures; ++j) a[i][j] = a[j][i] = m[at++];
        const double ridge = 1e-6 * n + 1e-9;
        for (int i = 0; i < kFeatures; ++i) a[i][i] += ridge;
        for (int j = 0; j < kFeatures; ++j) {  // in place: lower triangle L with L L^T = a
            double d = a[j][j];
            for (int k = 0; k < j; ++k) d -= a[j][k] * a[j][k];
            if (!(d > 0.0)) return std::max(0.0, s);
            a[j][j] = std::sqrt(d);
            for (int i = j + 1; i < kFeatures; ++i) {
                double x = a[i][j];
                for (int k = 0; k < j; ++k) x -= a[i][k] * a[j][k];
                a[i][j] = x / a[j][j];
            }
        }
        double z[kFeatures];  // L z = v; the explained part is |z|^2
        double explained = 0.0;
        for (int i = 0; i < kFeatures; ++i) {
            double x = v[i];
            for (int k = 0; k < i; ++k) x -= a[i][k] * z[k];
            z[i] = x / a[i][i];
            explained += z[i] * z[i];
        }
        return std::max(0.0, s - explained);
    }
};

struct BuildCell {
    format::TreeBox box;
    uint32_t depth = 0;
    uint32_t extra = 0;  // with PartitionSettings::gridRefine: tree levels under the grid's cell
    std::vector<uint32_t> samples;
    double residual = 0.0;
    int lower = -1, upper = -1;
    uint32_t axis = 0, split = 0;
    // The best split found for this cell, if any.
    bool canSplit = false;
    uint32_t bestAxis = 0, bestSplit = 0;
    double bestGain = 0.0;
    bool bestMakesNetwork = false;
};

struct Candidate {
    double priority;  // gain per byte
    uint32_t cell;
    bool operator<(const Candidate& o) const { return priority != o.priority ? priority < o.priority : cell > o.cell; }
};

}  // namespace

AdaptivePartition refinePartition(const format::Grid& lattice, const std::vector<TrainingSample>& samples,
                                  const std::vector<float>& learned, const format::Topology& topology,
                                  const PartitionSettings& settings, const MetadataReserve& reserve, const LeafScorer& scorer) {
    const float factor[3] = {eval::gridFactor(lattice, 0), eval::gridFactor(lattice, 1), eval::gridFactor(lattice, 2)};
    const size_t n = samples.size();
    // Each sample's lattice coordinate and features (position scaled to the box).
    std::vector<float> t(3 * n), features(kFeatures * n);
    float scale = 0.0f;
    for (int k = 0; k < 3; ++k) scale = std::max(scale, lattice.upper[k] - lattice.lower[k]);
    for (size_t i = 0; i < n; ++i) {
        const TrainingSample& s = samples[i];
        float* f = &features[kFeatures * i];
        f[0] = 1.0f;
        for (int k = 0; k < 3; ++k) {
            const float p = std::clamp(s.position[k], lattice.lower[k], lattice.upper[k]);
            t[3 * i + size_t(k)] = eval::gridCoordinate(p, lattice.lower[k], factor[k]);
            f[1 + k] = (p - lattice.lower[k]) / scale;
            f[4 + k] = s.normal[k];
            f[7 + k] = s.wo[k];
        }
    }
    const uint64_t perNetwork = 8 + topology.parameterCount() * topology.bytesPerWeight() + reserve.perNetwork;
    auto bytesOf = [&](uint64_t networks, uint64_t nodes) {
        return format::encodedSize(topology, networks, nodes, reserve.bytes(networks));
    };

    bool buildingGrid = settings.gridRefine > 0;  // while the grid's cells are cut (no other split meanwhile)
    std::vector<BuildCell> cells(1);
    for (int k = 0; k < 3; ++k) cells[0].box.hi[k] = lattice.dims[k];
    cells[0].samples.resize(n);
    for (size_t i = 0; i < n; ++i) cells[0].samples[i] = uint32_t(i);

    // Finds a cell's residual and best split: candidate planes at the eighths of each axis's extent (on the
    // lattice), the statistics of the samples between consecutive planes summed into both sides of each.
    auto evaluate = [&](BuildCell& c) {
        const size_t count = c.samples.size();
        const size_t stride = std::max<size_t>(1, (count + kMaxStatSamples - 1) / kMaxStatSamples);
        std::vector<uint32_t> planes[3];
        for (int k = 0; k < 3; ++k) {
            const uint32_t lo = c.box.lo[k], extent = c.box.hi[k] - c.box.lo[k];
            const uint32_t bins = std::max(1u, settings.candidatePlanes) + 1;
            for (uint32_t j = 1; j < bins; ++j) {
                const uint32_t plane = lo + uint32_t((uint64_t(extent) * j + bins / 2) / bins);
                if (plane > lo && plane < c.box.hi[k] && (planes[k].empty() || planes[k].back() != plane)) planes[k].push_back(plane);
            }
        }
        std::vector<Moments> bins[3];
        std::vector<size_t> binCount[3];
        for (int k = 0; k < 3; ++k) {
            bins[k].resize(planes[k].size() + 1);
            binCount[k].assign(planes[k].size() + 1, 0);
        }
        for (size_t j = 0; j < count; ++j) {
            const uint32_t i = c.samples[j];
            const bool used = j % stride == 0;
            for (int k = 0; k < 3; ++k) {
                const float tk = t[3 * size_t(i) + size_t(k)];
                const size_t bin = size_t(std::upper_bound(planes[k].begin(), planes[k].end(), tk,
                                                            [](float v, uint32_t plane) { return v < float(plane); }) -
                                           planes[k].begin());
                ++binCount[k][bin];
                if (used) bins[k][bin].add(&features[kFeatures * size_t(i)], learned[i]);
            }
        }
        Moments all;
        for (const Moments& m : bins[0]) all = all.plus(m);
        const double weight = double(stride);  // the statistics stand for every sample
        c.residual = all.residual() * weight;
        c.canSplit = false;
        for (int k = 0; k < 3; ++k) {
            Moments lower;
            size_t lo = 0;
            for (size_t j = 0; j < planes[k].size(); ++j) {
                lower = lower.plus(bins[k][j]);
                lo += binCount[k][j];
                const size_t hi = count - lo;
                if ((lo > 0 && lo < settings.minLeafSamples) || (hi > 0 && hi < settings.minLeafSamples)) continue;
                const double gain = c.residual - (lower.residual() + all.minus(lower).residual()) * weight;
                if (!c.canSplit || gain > c.bestGain) {
                    c.canSplit = true;
                    c.bestAxis = uint32_t(k);
                    c.bestSplit = planes[k][j];
                    c.bestGain = gain;
                    c.bestMakesNetwork = lo > 0 && hi > 0;
                }
            }
        }
        if (c.canSplit && !(c.bestGain > 0.0 && c.bestGain >= settings.minGainPerSample * double(count) &&
                            c.bestGain >= settings.minResidualShare * c.residual))
            c.canSplit = false;
        if (settings.gridRefine > 0 && (buildingGrid || c.extra >= settings.maxExtraDepth)) c.canSplit = false;
    };

    AdaptivePartition out;
    uint64_t networks = n > 0 ? 1 : 0, nodes = 1;
    if (bytesOf(std::max<uint64_t>(networks, 1), 1) > settings.budgetBytes)
        throw std::runtime_error("--budget " + std::to_string(settings.budgetBytes) + " bytes is below the smallest asset (one network: " +
                                 std::to_string(bytesOf(1, 1)) + " bytes)");
    std::priority_queue<Candidate> queue;
    evaluate(cells[0]);
    out.rootResidual = cells[0].residual;
    auto push = [&](uint32_t id) {
        const BuildCell& c = cells[id];
        if (!c.canSplit) return;
        const uint64_t cost = 16 + (c.bestMakesNetwork ? perNetwork : 0);
        queue.push({c.bestGain / double(cost), id});
    };
    // Splits cell `id` at its best plane if the budget allows; false (and counted) if not.
    auto split = [&](uint32_t id) {
        BuildCell& c = cells[id];
        const uint64_t nextNetworks = networks + (c.bestMakesNetwork ? 1 : 0);
        if (bytesOf(nextNetworks, nodes + 2) > settings.budgetBytes || c.depth + 1 > format::kMaxTreeDepth) {
            ++out.splitsSkippedForBudget;
            return false;
        }
        networks = nextNetworks;
        nodes += 2;
        BuildCell lo, hi;
        lo.box = hi.box = c.box;
        lo.box.hi[c.bestAxis] = c.bestSplit;
        hi.box.lo[c.bestAxis] = c.bestSplit;
        lo.depth = hi.depth = c.depth + 1;
        lo.extra = hi.extra = buildingGrid ? 0 : c.extra + 1;
        for (uint32_t i : c.samples)
            (t[3 * size_t(i) + c.bestAxis] < float(c.bestSplit) ? lo : hi).samples.push_back(i);
        std::vector<uint32_t>().swap(c.samples);
        c.axis = c.bestAxis;
        c.split = c.bestSplit;
        c.lower = int(cells.size());
        c.upper = int(cells.size() + 1);
        evaluate(lo);
        evaluate(hi);
        cells.push_back(std::move(lo));  // invalidates c
        cells.push_back(std::move(hi));
        return true;
    };

    // 1. By the residual, up to `residualShare` of the budget's networks (all of it without a scorer).
    const uint64_t perNetworkOnly = perNetwork + 16;
    const uint64_t fixed = bytesOf(0, 1);
    const uint64_t affordable = settings.budgetBytes > fixed ? (settings.budgetBytes - fixed) / perNetworkOnly : 0;
    const uint64_t phaseOne = scorer ? std::max<uint64_t>(1, uint64_t(double(affordable) * settings.residualShare)) : UINT64_MAX;
    if (settings.gridRefine > 0) {
        // The grid first: each cell wider than one grid voxel is cut at its middle multiple of gridRefine along
        // its widest axis (in grid voxels), whatever the gain, until the leaves are the grid's voxels.
        const uint32_t g = settings.gridRefine;
        std::vector<uint32_t> open{0}, leaves;
        while (!open.empty()) {
            const uint32_t id = open.back();
            open.pop_back();
            BuildCell& c = cells[id];
            uint32_t axis = 0, widest = 0;
            for (uint32_t k = 0; k < 3; ++k) {
                const uint32_t w = (c.box.hi[k] - c.box.lo[k]) / g;
                if (w > widest) widest = w, axis = k;
            }
            if (widest <= 1) {
                leaves.push_back(id);
                continue;
            }
            c.bestAxis = axis;
            c.bestSplit = c.box.lo[axis] + g * (widest / 2);
            size_t lo = 0;
            for (uint32_t i : c.samples) lo += t[3 * size_t(i) + axis] < float(c.bestSplit) ? 1 : 0;
            c.bestMakesNetwork = lo > 0 && lo < c.samples.size();
            if (!split(id)) throw std::logic_error("refinePartition: the grid does not fit the budget");
            open.push_back(uint32_t(cells.size() - 1));
            open.push_back(uint32_t(cells.size() - 2));
        }
        buildingGrid = false;
        for (uint32_t id : leaves) {
            evaluate(cells[id]);
            push(id);
        }
    } else {
        push(0);
    }
    while (!queue.empty() && networks < phaseOne) {
        const Candidate best = queue.top();
        queue.pop();
        if (!split(best.cell)) continue;
        push(uint32_t(cells.size() - 2));
        push(uint32_t(cells.size() - 1));
    }
    // 2. By the measured error: every leaf's network trained briefly, its held-out error x samples the
    //    score; the worst quarter (per byte) split each round, at their best planes, until the budget is spent.
    if (scorer) {
        std::vector<double> score(cells.size(), -1.0);
        for (int round = 0; round < 64; ++round) {
            std::vector<uint32_t> open, unscored;
            for (uint32_t id = 0; id < uint32_t(cells.size()); ++id)
                if (cells[id].lower < 0 && cells[id].canSplit) {
                    open.push_back(id);
                    if (score.size() <= id || score[id] < 0.0) unscored.push_back(id);
                }
            if (open.empty()) break;
            score.resize(cells.size(), -1.0);
            std::vector<const std::vector<uint32_t>*> sets;
            for (uint32_t id : unscored) sets.push_back(&cells[id].samples);
            const std::vector<double> scores = scorer(unscored, sets);
            for (size_t i = 0; i < unscored.size(); ++i) score[unscored[i]] = scores[i];
            std::vector<std::pair<double, uint32_t>> order;
            for (uint32_t id : open) {
                const uint64_t cost = 16 + (cells[id].bestMakesNetwork ? perNetwork : 0);
                order.emplace_back(score[id] / double(cost), id);
            }
            std::sort(order.begin(), order.end(), [](const auto& a, const auto& b) { return a.first != b.first ? a.first > b.first : a.second < b.second; });
            const size_t take = std::max<size_t>(1, (order.size() + 3) / 4);
            size_t made = 0;
            for (size_t i = 0; i < order.size() && made < take; ++i)
                if (split(order[i].second)) ++made;
            if (made == 0) break;  // nothing fits any more
        }
    }

    // Emit in the format's order: depth first, lower child first, children adjacent, leaves numbered.
    out.tree.assign(1, {});
    out.leafOfSample.assign(n, 0);
    struct Emit {
        std::vector<BuildCell>& cells;
        AdaptivePartition& out;
        void operator()(size_t id, uint32_t at) {
            BuildCell& c = cells[id];
            if (c.lower < 0) {
                const uint32_t leaf = out.leafCount++;
                out.tree[at] = {format::kTreeLeaf, 0, leaf};
                out.leaves.push_back({c.box, c.depth, uint32_t(c.samples.size()), c.residual});
                for (uint32_t i : c.samples) out.leafOfSample[i] = leaf;
                out.residual += c.residual;
                out.networks += c.samples.empty() ? 0 : 1;
                return;
            }
            const uint32_t child = uint32_t(out.tree.size());
            out.tree.resize(out.tree.size() + 2);
            out.tree[at] = {c.axis, c.split, child};
            (*this)(size_t(c.lower), child);
            (*this)(size_t(c.upper), child + 1);
        }
    };
    Emit{cells, out}(0, 0);
    out.bytes = bytesOf(out.networks, out.tree.size());
    return out;
}

uint32_t wallRefine(const format::Grid& grid) {
    const uint32_t widest = std::max({grid.dims[0], grid.dims[1], grid.dims[2], 1u});
    uint32_t refine = 1;
    while (refine < 256 && widest * refine * 2 <= format::kMaxGridDim) refine *= 2;
    return refine;
}

AdaptivePartition splitWalls(const format::Grid& grid, const std::vector<TrainingSample>& samples, const std::vector<float>& learned,
                             const WallSplitSettings& settings) {
    format::Grid lattice = grid;
    const uint32_t refine = wallRefine(grid);
    for (int k = 0; k < 3; ++k) lattice.dims[k] = grid.dims[k] * refine;
    PartitionSettings ps;
    ps.budgetBytes = std::numeric_limits<uint64_t>::max();
    ps.minLeafSamples = settings.minSideSamples;
    ps.measured = false;
    ps.candidatePlanes = refine - 1;  // every plane of the lattice
    ps.minGainPerSample = settings.minGainPerSample;
    ps.minResidualShare = settings.minResidualShare;
    ps.gridRefine = refine;
    ps.maxExtraDepth = settings.maxSplitsPerCell;
    format::Topology any;  // bytes are not limited here
    return refinePartition(lattice, samples, learned, any, ps, MetadataReserve{});
}

}  // namespace nrad
