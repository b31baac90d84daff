// Greedy kd-tree refinement by expected error reduction per byte.
#include "baker/bake/partition.h"

#include <algorithm>
#include <cmath>
#include <functional>
#include <limits>
#include <queue>
#include <stdexcept>
#include <string>

#include <nrad/eval.h>
#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>
#include <tbb/parallel_invoke.h>

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
    // One sample's terms (its products, exact in double: float x float has 48 significant bits), made once and
    // added to a bin of each axis.
    struct Terms {
        double m[kMoments], v[kFeatures], s;
        Terms(const float f[kFeatures], float y) {
            int at = 0;
            for (int i = 0; i < kFeatures; ++i) {
                for (int j = i; j < kFeatures; ++j) m[at++] = double(f[i]) * double(f[j]);
                v[i] = double(f[i]) * double(y);
            }
            s = double(y) * double(y);
        }
    };
    void add(const Terms& t) {
        for (int i = 0; i < kMoments; ++i) m[i] += t.m[i];
        for (int i = 0; i < kFeatures; ++i) v[i] += t.v[i];
        s += t.s;
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
    std::vector<float> t;  // the samples' lattice coordinates (3 each), beside them: read in order, not scattered
    double residual = 0.0;
    int lower = -1, upper = -1;
    uint32_t axis = 0, split = 0;
    // The best split found for this cell, if any.
    bool canSplit = false;
    uint32_t bestAxis = 0, bestSplit = 0;
    double bestGain = 0.0;
    bool bestMakesNetwork = false;
    bool hard = false;  // split at a hard plane (PartitionSettings::hardGap)
};

struct Candidate {
    double priority;  // gain per byte
    uint32_t cell;
    bool operator<(const Candidate& o) const { return priority != o.priority ? priority < o.priority : cell > o.cell; }
};

// The greedy refinement: the samples' lattice coordinates and features, the cells built so far (cells[0] the
// root; a split cell's two children appended), and the networks and tree nodes they cost.
class Refiner {
public:
    Refiner(const format::Grid& lattice, const std::vector<TrainingSample>& samples, const std::vector<float>& learned,
            const format::Topology& topology, const PartitionSettings& settings, const MetadataReserve& reserve)
        : settings_(settings), samples_(samples), learned_(learned), topology_(topology), reserve_(reserve), n_(samples.size()),
          perNetwork_(8 + topology.parameterCount() * topology.bytesPerWeight() + reserve.perNetwork),
          perLeafVolume_(settings.volumeNetworks * (8 + topology.parameterCount() * topology.bytesPerWeight())) {
        buildingGrid_ = settings.gridRefine > 0;
        cells_.resize(1);
        placeSamples(lattice, cells_[0].t);
        for (int k = 0; k < 3; ++k) cells_[0].box.hi[k] = lattice.dims[k];
        cells_[0].samples.resize(n_);
        for (size_t i = 0; i < n_; ++i) cells_[0].samples[i] = uint32_t(i);
    }

    AdaptivePartition run(const LeafScorer& scorer, const std::function<void(double)>& progress) {
        networks_ = n_ > 0 ? 1 : 0;
        if (bytesOf(std::max<uint64_t>(networks_, 1), 1) > settings_.budgetBytes)
            throw std::runtime_error("--budget " + std::to_string(settings_.budgetBytes) + " bytes is below the smallest asset (" +
                                     std::string(settings_.volumeNetworks ? "one network and its volume's, with the metadata: " : "one network: ") +
                                     std::to_string(bytesOf(1, 1)) + " bytes)");
        evaluate(cells_[0]);
        out_.rootResidual = cells_[0].residual;
        // 1. By the residual, up to `residualShare` of the budget's networks (all of it without a scorer).
        const uint64_t perNetworkOnly = perNetwork_ + perLeafVolume_ + 16;
        const uint64_t fixed = bytesOf(0, 1);
        const uint64_t affordable = settings_.budgetBytes > fixed ? (settings_.budgetBytes - fixed) / perNetworkOnly : 0;
        const uint64_t phaseOne = scorer ? std::max<uint64_t>(1, uint64_t(double(affordable) * settings_.residualShare)) : UINT64_MAX;
        if (settings_.gridRefine > 0) {
            cutGrid();
        } else {
            push(0);
        }
        // Progress: the networks made of those the budget pays for, reported at every whole percent.
        int reported = -1;
        auto report = [&] {
            const int percent = affordable > 0 ? int(std::min<uint64_t>(100, 100 * networks_ / affordable)) : 100;
            if (progress && percent != reported) progress(double(reported = percent) / 100.0);
        };
        while (!queue_.empty() && networks_ < phaseOne) {
            const Candidate best = queue_.top();
            queue_.pop();
            if (!split(best.cell)) continue;
            push(uint32_t(cells_.size() - 2));
            push(uint32_t(cells_.size() - 1));
            if (settings_.budgetBytes != UINT64_MAX) report();
        }
        if (scorer) refineByScore(scorer, report);
        if (progress && settings_.budgetBytes != UINT64_MAX) progress(1.0);
        // Emit in the format's order: depth first, lower child first, children adjacent, leaves numbered.
        out_.tree.assign(1, {});
        out_.leafOfSample.assign(n_, 0);
        emit(0, 0);
        out_.bytes = bytesOf(out_.networks, out_.tree.size());
        return std::move(out_);
    }

private:
    const PartitionSettings& settings_;
    const std::vector<TrainingSample>& samples_;
    const std::vector<float>& learned_;
    const format::Topology& topology_;
    const MetadataReserve& reserve_;
    const size_t n_;
    const uint64_t perNetwork_;
    const uint64_t perLeafVolume_;  // the volume's networks a leaf may get (PartitionSettings::volumeNetworks)
    glm::vec3 lower_{0.0f}, upper_{0.0f};
    float featureScale_ = 0.0f;
    bool buildingGrid_ = false;  // while the grid's cells are cut (no other split meanwhile)
    std::vector<BuildCell> cells_;
    std::priority_queue<Candidate> queue_;
    uint64_t networks_ = 0, nodes_ = 1;
    AdaptivePartition out_;

    // A tree of `nodes` nodes has (nodes + 1) / 2 leaves, each with a volume network (and a glossy one) at most.
    uint64_t bytesOf(uint64_t networks, uint64_t nodes) const {
        const uint64_t leaves = (nodes + 1) / 2;
        return format::encodedSize(topology_, networks, nodes, reserve_.bytes(networks), settings_.volumeNetworks >= 1 ? leaves : 0,
                                   settings_.volumeNetworks >= 2 ? leaves : 0);
    }

    // Each sample's lattice coordinate (into t, 3 a sample: the root cell's), and what its features need: the
    // lattice's lower corner and the scale that makes positions relative to it.
    void placeSamples(const format::Grid& lattice, std::vector<float>& t) {
        const float factor[3] = {eval::gridFactor(lattice, 0), eval::gridFactor(lattice, 1), eval::gridFactor(lattice, 2)};
        t.resize(3 * n_);
        for (int k = 0; k < 3; ++k) featureScale_ = std::max(featureScale_, lattice.upper[k] - lattice.lower[k]);
        lower_ = glm::vec3(lattice.lower[0], lattice.lower[1], lattice.lower[2]);
        upper_ = glm::vec3(lattice.upper[0], lattice.upper[1], lattice.upper[2]);
        for (size_t i = 0; i < n_; ++i)
            for (int k = 0; k < 3; ++k) {
                const float p = std::clamp(samples_[i].position[k], lower_[k], upper_[k]);
                t[3 * i + size_t(k)] = eval::gridCoordinate(p, lattice.lower[k], factor[k]);
            }
    }

    // Sample i's features: 1, its position scaled to the lattice's box, its normal and direction (made when needed,
    // not stored: 40 bytes a sample, 157 MB for a bake of 3.9 M samples).
    void featuresOf(size_t i, float f[kFeatures]) const {
        const TrainingSample& s = samples_[i];
        f[0] = 1.0f;
        for (int k = 0; k < 3; ++k) {
            f[1 + k] = (std::clamp(s.position[k], lower_[k], upper_[k]) - lower_[k]) / featureScale_;
            f[4 + k] = s.normal[k];
            f[7 + k] = s.wo[k];
        }
    }

    // A cell's candidate planes: at the eighths (settings.candidatePlanes) of each axis's extent, on the lattice.
    void candidatePlanes(const BuildCell& c, std::vector<uint32_t> planes[3]) const {
        for (int k = 0; k < 3; ++k) {
            const uint32_t lo = c.box.lo[k], extent = c.box.hi[k] - c.box.lo[k];
            const uint32_t bins = std::max(1u, settings_.candidatePlanes) + 1;
            for (uint32_t j = 1; j < bins; ++j) {
                const uint32_t plane = lo + uint32_t((uint64_t(extent) * j + bins / 2) / bins);
                if (plane > lo && plane < c.box.hi[k] && (planes[k].empty() || planes[k].back() != plane)) planes[k].push_back(plane);
            }
        }
    }

    // Finds a cell's residual and best split: the statistics of the samples between consecutive candidate
    // planes summed into both sides of each.
    void evaluate(BuildCell& c) const {
        const size_t count = c.samples.size();
        const size_t stride = std::max<size_t>(1, (count + kMaxStatSamples - 1) / kMaxStatSamples);
        std::vector<uint32_t> planes[3];
        candidatePlanes(c, planes);
        std::vector<Moments> bins[3];
        std::vector<size_t> binCount[3];
        for (int k = 0; k < 3; ++k) {
            bins[k].resize(planes[k].size() + 1);
            binCount[k].assign(planes[k].size() + 1, 0);
        }
        // The features of a cell's samples lie scattered over the bake's (a 1 MB zdm2 bake's 4 M samples: 256 MB), so
        // that nearly every read missed the caches: each is fetched kAhead used samples ahead.
        constexpr size_t kAhead = 16;
        for (size_t j = 0; j < count; ++j) {
            if (j % stride == 0 && j + kAhead * stride < count) {
                const uint32_t ahead = c.samples[j + kAhead * stride];
                __builtin_prefetch(&samples_[ahead].position);
                __builtin_prefetch(&samples_[ahead].wo);
                __builtin_prefetch(&learned_[ahead]);
            }
            const uint32_t i = c.samples[j];
            size_t bin[3];
            for (int k = 0; k < 3; ++k) {
                const float tk = c.t[3 * j + size_t(k)];
                bin[k] = size_t(std::upper_bound(planes[k].begin(), planes[k].end(), tk,
                                                 [](float v, uint32_t plane) { return v < float(plane); }) -
                                planes[k].begin());
                ++binCount[k][bin[k]];
            }
            if (j % stride != 0) continue;
            float f[kFeatures];
            featuresOf(i, f);
            const Moments::Terms terms(f, learned_[i]);
            for (int k = 0; k < 3; ++k) bins[k][bin[k]].add(terms);
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
                if ((lo > 0 && lo < settings_.minLeafSamples) || (hi > 0 && hi < settings_.minLeafSamples)) continue;
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
        if (c.canSplit && !(c.bestGain > 0.0 && c.bestGain >= settings_.minGainPerSample * double(count) &&
                            c.bestGain >= settings_.minResidualShare * c.residual))
            c.canSplit = false;
        if (settings_.gridRefine > 0 && (buildingGrid_ || c.extra >= settings_.maxExtraDepth)) c.canSplit = false;
    }

    // What splitting cell `id` at its best plane costs: two nodes, a leaf's volume networks, and a network if both
    // sides have samples.
    uint64_t splitCost(uint32_t id) const { return 16 + perLeafVolume_ + (cells_[id].bestMakesNetwork ? perNetwork_ : 0); }

    void push(uint32_t id) {
        const BuildCell& c = cells_[id];
        if (!c.canSplit) return;
        queue_.push({c.bestGain / double(splitCost(id)), id});
    }

    // Splits cell `id` at its best plane if the budget allows; false (and counted) if not. The two new cells (the
    // last two) are evaluated, in parallel, unless `evaluateChildren` is false (then the caller evaluates them).
    bool split(uint32_t id, bool evaluateChildren = true) {
        BuildCell& c = cells_[id];
        const uint64_t nextNetworks = networks_ + (c.bestMakesNetwork ? 1 : 0);
        if (bytesOf(nextNetworks, nodes_ + 2) > settings_.budgetBytes || c.depth + 1 > format::kMaxTreeDepth) {
            ++out_.splitsSkippedForBudget;
            return false;
        }
        networks_ = nextNetworks;
        nodes_ += 2;
        BuildCell lo, hi;
        lo.box = hi.box = c.box;
        lo.box.hi[c.bestAxis] = c.bestSplit;
        hi.box.lo[c.bestAxis] = c.bestSplit;
        lo.depth = hi.depth = c.depth + 1;
        lo.extra = hi.extra = buildingGrid_ ? 0 : c.extra + 1;
        const bool mayBeHard = settings_.hardGap > 0.0f && !buildingGrid_;
        if (mayBeHard) {
            // Every plane between the last sample below and the first above splits the samples alike: the one
            // nearest the middle of that gap (a wall's inside), so that the plane clears both faces; hard where
            // both are hardGap away or more.
            float below = -std::numeric_limits<float>::infinity(), above = std::numeric_limits<float>::infinity();
            for (size_t j = 0; j < c.samples.size(); ++j) {
                const float t = c.t[3 * j + c.bestAxis];
                if (t < float(c.bestSplit)) below = std::max(below, t);
                else above = std::min(above, t);
            }
            if (std::isfinite(below) && std::isfinite(above)) {
                const float middle = std::floor(0.5f * (below + above) + 0.5f);
                if (middle > below && middle <= above && middle > float(c.box.lo[c.bestAxis]) && middle < float(c.box.hi[c.bestAxis])) {
                    c.bestSplit = uint32_t(middle);
                    lo.box.hi[c.bestAxis] = c.bestSplit;
                    hi.box.lo[c.bestAxis] = c.bestSplit;
                }
            }
            c.hard = std::min(float(c.bestSplit) - below, above - float(c.bestSplit)) >= settings_.hardGap;
        }
        size_t lowerCount = 0;
        for (size_t j = 0; j < c.samples.size(); ++j) lowerCount += c.t[3 * j + c.bestAxis] < float(c.bestSplit) ? 1 : 0;
        lo.samples.reserve(lowerCount);
        lo.t.reserve(3 * lowerCount);
        hi.samples.reserve(c.samples.size() - lowerCount);
        hi.t.reserve(3 * (c.samples.size() - lowerCount));
        for (size_t j = 0; j < c.samples.size(); ++j) {
            BuildCell& side = c.t[3 * j + c.bestAxis] < float(c.bestSplit) ? lo : hi;
            side.samples.push_back(c.samples[j]);
            side.t.insert(side.t.end(), &c.t[3 * j], &c.t[3 * j] + 3);
        }
        std::vector<uint32_t>().swap(c.samples);
        std::vector<float>().swap(c.t);
        c.axis = c.bestAxis;
        c.split = c.bestSplit;
        c.lower = int(cells_.size());
        c.upper = int(cells_.size() + 1);
        if (evaluateChildren) tbb::parallel_invoke([&] { evaluate(lo); }, [&] { evaluate(hi); });
        cells_.push_back(std::move(lo));  // invalidates c
        cells_.push_back(std::move(hi));
        return true;
    }

    // Evaluates cells [from, cells_.size()), in parallel (each cell's evaluation is its own: the same result in any order).
    void evaluateFrom(size_t from) {
        tbb::parallel_for(tbb::blocked_range<size_t>(from, cells_.size(), 1), [&](const tbb::blocked_range<size_t>& r) {
            for (size_t id = r.begin(); id != r.end(); ++id) evaluate(cells_[id]);
        });
    }

    // The grid first: each cell wider than one grid voxel is cut at its middle multiple of gridRefine along
    // its widest axis (in grid voxels), whatever the gain, until the leaves are the grid's voxels.
    void cutGrid() {
        const uint32_t g = settings_.gridRefine;
        std::vector<uint32_t> open{0}, leaves;
        while (!open.empty()) {
            const uint32_t id = open.back();
            open.pop_back();
            BuildCell& c = cells_[id];
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
            for (size_t j = 0; j < c.samples.size(); ++j) lo += c.t[3 * j + axis] < float(c.bestSplit) ? 1 : 0;
            c.bestMakesNetwork = lo > 0 && lo < c.samples.size();
            if (!split(id, false)) throw std::logic_error("refinePartition: the grid does not fit the budget");  // (no split while building it)
            open.push_back(uint32_t(cells_.size() - 1));
            open.push_back(uint32_t(cells_.size() - 2));
        }
        buildingGrid_ = false;
        tbb::parallel_for(size_t(0), leaves.size(), [&](size_t i) { evaluate(cells_[leaves[i]]); });
        for (uint32_t id : leaves) push(id);
    }

    // 2. By the measured error: every leaf's network trained briefly, its held-out error x samples the
    //    score; the worst quarter (per byte) split each round, at their best planes, until the budget is spent.
    void refineByScore(const LeafScorer& scorer, const std::function<void()>& report) {
        std::vector<double> score(cells_.size(), -1.0);
        for (int round = 0; round < 64; ++round) {
            std::vector<uint32_t> open, unscored;
            for (uint32_t id = 0; id < uint32_t(cells_.size()); ++id)
                if (cells_[id].lower < 0 && cells_[id].canSplit) {
                    open.push_back(id);
                    if (score.size() <= id || score[id] < 0.0) unscored.push_back(id);
                }
            if (open.empty()) break;
            score.resize(cells_.size(), -1.0);
            std::vector<const std::vector<uint32_t>*> sets;
            for (uint32_t id : unscored) sets.push_back(&cells_[id].samples);
            const std::vector<double> scores = scorer(unscored, sets);
            for (size_t i = 0; i < unscored.size(); ++i) score[unscored[i]] = scores[i];
            std::vector<std::pair<double, uint32_t>> order;
            for (uint32_t id : open) order.emplace_back(score[id] / double(splitCost(id)), id);
            std::sort(order.begin(), order.end(), [](const auto& a, const auto& b) { return a.first != b.first ? a.first > b.first : a.second < b.second; });
            const size_t take = std::max<size_t>(1, (order.size() + 3) / 4);
            size_t made = 0;
            const size_t firstNew = cells_.size();
            for (size_t i = 0; i < order.size() && made < take; ++i)  // (a split's cost does not depend on its children)
                if (split(order[i].second, false)) ++made;
            evaluateFrom(firstNew);
            if (made == 0) break;  // nothing fits any more
            report();
        }
    }

    // Writes cell `id` (and its subtree) at tree node `at`.
    void emit(size_t id, uint32_t at) {
        BuildCell& c = cells_[id];
        if (c.lower < 0) {
            const uint32_t leaf = out_.leafCount++;
            out_.tree[at] = {format::kTreeLeaf, 0, leaf};
            out_.leaves.push_back({c.box, c.depth, uint32_t(c.samples.size()), c.residual});
            for (uint32_t i : c.samples) out_.leafOfSample[i] = leaf;
            out_.residual += c.residual;
            out_.networks += c.samples.empty() ? 0 : 1;
            return;
        }
        const uint32_t child = uint32_t(out_.tree.size());
        out_.tree.resize(out_.tree.size() + 2);
        out_.tree[at] = {c.axis, c.split, child, c.hard};
        emit(size_t(c.lower), child);
        emit(size_t(c.upper), child + 1);
    }
};

}  // namespace

AdaptivePartition refinePartition(const format::Grid& lattice, const std::vector<TrainingSample>& samples,
                                  const std::vector<float>& learned, const format::Topology& topology,
                                  const PartitionSettings& settings, const MetadataReserve& reserve, const LeafScorer& scorer,
                                  const std::function<void(double)>& progress) {
    return Refiner(lattice, samples, learned, topology, settings, reserve).run(scorer, progress);
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
    ps.hardGap = settings.hardGap;
    format::Topology any;  // bytes are not limited here
    return refinePartition(lattice, samples, learned, any, ps, MetadataReserve{});
}

}  // namespace nrad
