// The bake pipeline.
#include "baker/bake/baker.h"

#include <chrono>
#include <algorithm>
#include <atomic>
#include <cmath>
#include <cstdio>
#include <limits>
#include <memory>
#include <stdexcept>
#include <string>

#include <nlohmann/json.hpp>
#include <tbb/parallel_for.h>

#include "baker/bake/network_field.h"
#include "baker/nn/schedule.h"
#include "baker/render/accel.h"
#include "baker/lights/light_sampler.h"
#include "baker/render/path_tracer.h"
#include "baker/util/hash.h"

namespace nrad {

namespace {
double since(std::chrono::steady_clock::time_point t) {
    return std::chrono::duration<double>(std::chrono::steady_clock::now() - t).count();
}

template <typename T>
void hashBytes(uint64_t& h, const T* data, size_t count) {
    fnv1a(h, data, count * sizeof(T));
}

// Which process trains each of `count` networks (their costs: their samples); all of them this one's without a group.
std::vector<int> networkOwners(const std::vector<double>& costs, const BakeGroup* group) {
    return group && group->size() > 1 ? assignByCost(costs, group->size()) : std::vector<int>(costs.size(), 0);
}

// The partition's measured phase: each cell's network trained briefly on (up to 2,000 of) its own samples,
// positions relative to their bounding box; what it leaves is its held-out relMSE times the cell's samples. With a
// group, each process trains its share of the cells and the scores are exchanged.
LeafScorer briefTrainingScorer(const std::vector<TrainingSample>& samples, const TrainSettings& train, const BakeGroup* group) {
    TrainSettings quick = train;
    quick.epochs = std::min(quick.epochs, 150);
    quick.patience = std::min(quick.patience, 50);
    quick.weightDecays.resize(1);
    quick.restarts = 1;  // a brief score, not a network to keep
    quick.raceEpochs = 0;
    quick.maxAttempts = 1;
    quick.curveEvery = 1 << 30;
    return [&samples, quick, group](const std::vector<uint32_t>& ids, const std::vector<const std::vector<uint32_t>*>& sets) {
        std::vector<double> costs;
        for (const std::vector<uint32_t>* set : sets) costs.push_back(double(std::min<size_t>(set->size(), 2000)));
        const std::vector<int> owner = networkOwners(costs, group);
        const int rank = group ? group->rank() : 0;
        // Each cell's (up to 2,000) samples, positions relative to their bounding box, in parallel; then every
        // cell's network trained at once.
        std::vector<std::vector<VoxelSample>> inputs(ids.size());
        tbb::parallel_for(tbb::blocked_range<size_t>(0, ids.size(), 1), [&](const tbb::blocked_range<size_t>& r) {
            for (size_t k = r.begin(); k != r.end(); ++k) {
                const std::vector<uint32_t>& set = *sets[k];
                if (set.empty() || owner[k] != rank) continue;
                const size_t stride = std::max<size_t>(1, (set.size() + 1999) / 2000);
                glm::vec3 lo(1e30f), hi(-1e30f);
                for (uint32_t i : set) {
                    lo = glm::min(lo, samples[i].position);
                    hi = glm::max(hi, samples[i].position);
                }
                const glm::vec3 extent = glm::max(hi - lo, glm::vec3(1e-6f));
                for (size_t j = 0; j < set.size(); j += stride)
                    inputs[k].push_back({&samples[set[j]], 1.0f, 2.0f * (samples[set[j]].position - lo) / extent - 1.0f});
            }
        });
        std::vector<uint32_t> trained;
        std::vector<const std::vector<VoxelSample>*> trainedSamples;
        for (size_t k = 0; k < ids.size(); ++k)
            if (!inputs[k].empty()) {
                trained.push_back(ids[k]);
                trainedSamples.push_back(&inputs[k]);
            }
        const std::vector<VoxelTrainResult> results = trainVoxels(trained, trainedSamples, quick);
        std::vector<double> out(ids.size(), 0.0);
        for (size_t k = 0, t = 0; k < ids.size(); ++k)
            if (!inputs[k].empty()) out[k] = results[t++].heldOutRelMse * double(sets[k]->size());
        if (group && group->size() > 1) {  // every process's scores
            ByteWriter w;
            for (size_t k = 0; k < ids.size(); ++k)
                if (owner[k] == rank) w.put(out[k]);
            const std::vector<std::vector<uint8_t>> all = group->allGather(w.bytes);
            std::vector<ByteReader> in;
            for (const std::vector<uint8_t>& bytes : all) in.emplace_back(bytes);
            for (size_t k = 0; k < ids.size(); ++k) out[k] = in[size_t(owner[k])].get<double>();
        }
        return out;
    };
}
// The cell of a sample's point (inside the box up to rounding: clamped into it, where treeLeaf always finds one).
uint32_t cellOfPoint(const eval::Partition& partition, const glm::vec3& p) {
    float q[3];
    for (int k = 0; k < 3; ++k) q[k] = std::clamp(p[k], partition.grid.lower[k], partition.grid.upper[k]);
    const int64_t c = partition.cellOf(q);
    return c >= 0 ? uint32_t(c) : 0u;  // only for a non-finite point, which no sample has
}

// The position input of a sample in its own cell when it lies just outside the box (samplesByNetwork).
glm::vec3 positionInCell(const eval::Partition& partition, const AdaptivePartition& ap, bool adaptive, const VoxelGrid& grid,
                         const glm::vec3& p, uint32_t cell) {
    if (!adaptive) return grid.positionInVoxel(p, cell);
    const format::TreeBox& b = ap.leaves[cell].box;
    glm::vec3 local;
    for (int k = 0; k < 3; ++k) {
        const float t = std::clamp(eval::gridCoordinate(p[k], partition.grid.lower[k], partition.factor[k]), 0.0f,
                                   float(partition.grid.dims[k]));
        local[k] = eval::clampUnit(eval::localInBox(t, b.lo[k], b.hi[k]));
    }
    return local;
}

// The volume's networks per cell: none, 1, or 2 with its glossy response.
uint32_t volumeSets(const BakeSettings& s) { return s.volume.enabled ? (s.volume.glossy ? 2u : 1u) : 0u; }
}  // namespace

uint32_t roundPoints(size_t networks) { return uint32_t(std::clamp<size_t>(2000 * networks, 50000, 4000000)); }

const char* trainingMethodName(TrainingMethod method) { return method == TrainingMethod::Integral ? "integral" : "monte-carlo"; }

bool parseTrainingMethod(const std::string& name, TrainingMethod& method) {
    for (TrainingMethod m : {TrainingMethod::MonteCarlo, TrainingMethod::Integral})
        if (name == trainingMethodName(m)) {
            method = m;
            return true;
        }
    return false;
}

uint64_t sceneHash(const Scene& scene) {
    uint64_t h = kFnvOffsetBasis;
    hashBytes(h, scene.mesh.positions.data(), scene.mesh.positions.size());
    hashBytes(h, scene.mesh.normals.data(), scene.mesh.normals.size());
    hashBytes(h, scene.mesh.triangles.data(), scene.mesh.triangles.size());
    hashBytes(h, scene.mesh.materialIds.data(), scene.mesh.materialIds.size());
    for (const Material& m : scene.materials) {
        float f[] = {m.baseColor.x, m.baseColor.y, m.baseColor.z, m.metallic, m.roughness, m.emission.x, m.emission.y,
                     m.emission.z, m.specular, m.specularColor.x, m.specularColor.y, m.specularColor.z, m.ior, float(m.doubleSided),
                     float(m.baseColorTexture.texture), float(m.emissiveTexture.texture), float(m.metallicRoughnessTexture.texture)};
        hashBytes(h, f, sizeof f / sizeof f[0]);
    }
    for (const Texture& t : scene.textures)
        for (size_t i = 0, n = t.texelCount(); i < n; ++i) {  // the decoded texels, however they are stored
            const glm::vec4 texel = t.texel(i);
            hashBytes(h, &texel, 1);
        }
    for (const PunctualLight& l : scene.lights) {
        float f[] = {float(l.type), l.position.x, l.position.y, l.position.z, l.direction.x, l.direction.y, l.direction.z,
                     l.intensity.x, l.intensity.y, l.intensity.z, l.cosInnerCone, l.cosOuterCone};
        hashBytes(h, f, sizeof f / sizeof f[0]);
    }
    // Soft suns and lights the engine draws (only when set, so other scenes keep their hashes).
    for (const PunctualLight& l : scene.lights)
        if (l.soft() || l.runtimeDirect) {
            float f[] = {l.cosAngularRadius, float(l.runtimeDirect)};
            hashBytes(h, f, 2);
        }
    // The environment lights the scene too (only when active, so scenes lit by their own lights keep the
    // hashes, and the cached references, they had before environments existed).
    if (const Environment& e = scene.environment; e.active()) {
        float f[] = {float(e.kind), e.color.x, e.color.y, e.color.z, e.intensity, e.rotationDegrees, float(e.width), float(e.height)};
        hashBytes(h, f, sizeof f / sizeof f[0]);
        hashBytes(h, e.texels.data(), e.texels.size());
    }
    return h;
}

static nlohmann::json environmentMetadata(const Environment& e) {
    if (!e.active()) return {{"kind", "none"}};
    nlohmann::json j = {{"kind", e.kind == Environment::Kind::Map ? "map" : "constant"},
                        {"source", e.source},
                        {"intensity", e.intensity},
                        {"rotation_degrees", e.rotationDegrees},
                        {"default", e.isDefault},
                        {"description", e.describe()}};
    if (e.kind == Environment::Kind::Constant) j["color"] = {e.color.x, e.color.y, e.color.z};
    if (e.kind == Environment::Kind::Map) j["size"] = {e.width, e.height};
    return j;
}

namespace {

// What the bake traces with: the scene's rays, its lights and their selection, the path tracer of the
// training targets, and the voxel grid with the surface in each voxel.
struct BakeTracing {
    Accel accel;
    LightSampler lights;
    LightSelector selector;
    PathTracer tracer;
    VoxelGrid grid;
    SurfacePieces pieces;

    static NeeSettings seeded(const BakeSettings& settings) {
        NeeSettings nee = settings.nee;
        nee.seed ^= settings.samples.seed;
        return nee;
    }
    BakeTracing(const Scene& scene, const BakeSettings& settings)
        : accel(scene),
          lights(scene),
          selector(lights, scene.bounds, seeded(settings)),
          tracer(scene, accel, lights, &selector),
          grid(scene.bounds, settings.grid),
          pieces(scene.mesh, grid) {
        tracer.setExcludeEngineDrawnDirect(true);  // mixed lighting: the asset holds those lights' indirect light only
        tracer.setRouletteThreshold(kTrainingRouletteThreshold);
    }
};

// The cells the networks cover (the grid's voxels, or the leaves of a tree on `lattice`: `adaptive`) and the
// samples of each cell's network.
struct BakeCells {
    format::Grid lattice;
    float band = 0.0f;
    bool budgeted = false, adaptive = false;
    MetadataReserve reserve;  // what a budgeted asset keeps for its metadata
    std::vector<std::vector<VoxelSample>> byVoxel;
};

// What the partition sees of a sample: log(0.1 + its learned luminance).
std::vector<float> learnedValues(const std::vector<TrainingSample>& samples, bool demodulate) {
    std::vector<float> learned(samples.size());
    for (size_t i = 0; i < samples.size(); ++i) {
        const glm::vec3 y = demodulate ? samples[i].radiance / demodulationDivisor(samples[i]) : samples[i].radiance;
        learned[i] = float(std::log(std::max(0.0, luminance(y)) + 0.1));
    }
    return learned;
}

// The metadata's bytes, exactly: a budgeted asset's metadata leaves out the per-network error list (--stats
// has it), so it depends on nothing that refining changes.
MetadataReserve metadataReserve(const Scene& scene, const BakeSettings& settings, const BakeResult& result) {
    if (!settings.metadata) return {};
    BakeResult none;
    none.sampleCount = result.sampleCount;
    if (settings.training == TrainingMethod::Integral) {
        // The rounds add samples and set their points by the networks: reserve their largest numbers.
        none.sampleCount = std::numeric_limits<uint32_t>::max();
        none.voxels.resize(2000);  // roundPoints' cap
    }
    return {assetMetadata(scene, settings, none).size(), 0};
}

eval::Partition cellPartition(const BakeCells& cells, const AdaptivePartition& ap) {
    return cells.adaptive ? eval::Partition(cells.lattice, cells.band, ap.tree, ap.leafCount)
                          : eval::Partition(cells.lattice, cells.band, {}, 0);
}

// The cells and each one's samples (its own, plus its neighbours' within the blending band, in the fixed
// sample order): the grid's voxels, split at walls, or with a budget the leaves of the adaptive tree,
// refined on these very samples (into result.partition).
BakeCells partitionCells(const Scene& scene, const BakeSettings& settings, const VoxelGrid& grid,
                         const std::vector<TrainingSample>& samples, const format::Topology& topology, const BakeProgress& progress,
                         BakeResult& result, const BakeGroup* group) {
    BakeCells cells;
    cells.band = std::clamp(settings.blendBand, 0.0f, format::kMaxBlendBand);
    cells.budgeted = settings.partition.budgetBytes > 0;
    cells.lattice = grid.grid();
    std::vector<float> learned;
    if (cells.budgeted || settings.walls.enabled) learned = learnedValues(samples, settings.train.demodulate);
    bool walled = false;  // the grid with its cells split at walls: a tree on a finer lattice
    if (!cells.budgeted && settings.walls.enabled) {
        AdaptivePartition ap = splitWalls(grid.grid(), samples, learned, settings.walls);
        const format::Grid& g = grid.grid();
        if (ap.leafCount > g.dims[0] * g.dims[1] * g.dims[2]) {
            walled = true;
            result.partition = std::move(ap);
            for (int k = 0; k < 3; ++k) cells.lattice.dims[k] = g.dims[k] * wallRefine(g);
        }
    }
    cells.adaptive = cells.budgeted || walled;  // the cells are a tree's leaves
    if (cells.budgeted) {
        cells.lattice = VoxelGrid(scene.bounds, latticeDims(scene.bounds, settings.partition.levels)).grid();
        cells.reserve = metadataReserve(scene, settings, result);
        PartitionSettings partition = settings.partition;
        partition.volumeNetworks = volumeSets(settings);  // the volume's networks in the budget too
        result.partition = refinePartition(cells.lattice, samples, learned, topology, partition, cells.reserve,
                                           settings.partition.measured ? briefTrainingScorer(samples, settings.train, group) : LeafScorer(),
                                           progress.partition);
    }
    if (cells.adaptive) {
        const AdaptivePartition& ap = result.partition;
        const eval::Partition partition = cellPartition(cells, ap);
        cells.byVoxel = samplesByNetwork(partition, ap.leafOfSample, samples, [&](size_t i) {
            return positionInCell(partition, ap, true, grid, samples[i].position, ap.leafOfSample[i]);
        });
    } else {
        cells.byVoxel = samplesByNetwork(grid, cells.band, samples);
    }
    return cells;
}

// What the first training of the networks runs with: the settings, or for training within the integral
// equation its short start (IntegralSettings).
TrainSettings startTrainSettings(const BakeSettings& settings) {
    TrainSettings start = settings.train;
    if (settings.training == TrainingMethod::Integral) {
        start.epochs = std::min(start.epochs, settings.integral.startEpochs);
        start.patience = std::min(start.patience, settings.integral.startPatience);
        if (start.weightDecays.size() > 1) start.weightDecays.resize(1);
        start.restarts = settings.integral.restarts();
        start.raceEpochs = 0;  // the start's restarts (IntegralSettings) each train to their end, as they were measured
    }
    return start;
}

// A network's result as bytes, and back (the processes of a bake exchange them).
void putResult(ByteWriter& w, const VoxelTrainResult& v) {
    w.put(v.voxel);
    w.putVector(v.params);
    w.put(v.scale);
    w.put(v.transform);
    w.put(uint64_t(v.trainCount));
    w.put(uint64_t(v.heldOutCount));
    w.put(v.heldOutRelMse);
    w.put(v.trainRelMse);
    w.put(v.epochs);
    w.put(v.attempts);
    w.put(v.fallback);
    w.put(v.weightDecay);
    w.put(uint64_t(v.events.size()));
    for (const std::string& e : v.events) w.putString(e);
    w.putVector(v.curve);
    w.put(v.seconds);
}

VoxelTrainResult getResult(ByteReader& in) {
    VoxelTrainResult v;
    v.voxel = in.get<uint32_t>();
    v.params = in.getVector<float>();
    v.scale = in.get<float>();
    v.transform = in.get<format::OutputTransform>();
    v.trainCount = size_t(in.get<uint64_t>());
    v.heldOutCount = size_t(in.get<uint64_t>());
    v.heldOutRelMse = in.get<double>();
    v.trainRelMse = in.get<double>();
    v.epochs = in.get<int>();
    v.attempts = in.get<int>();
    v.fallback = in.get<bool>();
    v.weightDecay = in.get<float>();
    const uint64_t events = in.get<uint64_t>();
    for (uint64_t e = 0; e < events; ++e) v.events.push_back(in.getString());
    v.curve = in.getVector<TrainCurvePoint>();
    v.seconds = in.get<double>();
    return v;
}

// Every process's networks (`owner`) into `all` on every process, from each one's own in `all`.
void exchangeResults(const BakeGroup* group, const std::vector<int>& owner, std::vector<VoxelTrainResult>& all) {
    if (!group || !group->exchanges()) return;
    ByteWriter w;
    for (size_t k = 0; k < all.size(); ++k)
        if (owner[k] == group->rank()) {
            w.put(uint64_t(k));
            putResult(w, all[k]);
        }
    for (const std::vector<uint8_t>& bytes : group->allGather(w.bytes)) {
        ByteReader in(bytes);
        while (!in.done()) {
            const uint64_t k = in.get<uint64_t>();
            if (k >= all.size()) throw std::runtime_error("bake group: a network out of range");
            all[size_t(k)] = getResult(in);
        }
    }
}

// Trains every occupied cell's network, in parallel (and with a group, this process its share), into result.voxels;
// returns the process that trained each.
std::vector<int> trainCells(const BakeSettings& settings, const BakeCells& cells, const BakeProgress& progress, BakeResult& result,
                const BakeGroup* group) {
    std::vector<uint32_t> occupied;
    for (uint32_t v = 0; v < uint32_t(cells.byVoxel.size()); ++v)
        if (!cells.byVoxel[v].empty()) occupied.push_back(v);
    std::vector<double> costs;
    for (uint32_t v : occupied) costs.push_back(double(cells.byVoxel[v].size()));
    const std::vector<int> owner = networkOwners(costs, group);
    const int rank = group ? group->rank() : 0;
    const TrainSettings start = startTrainSettings(settings);
    std::vector<uint32_t> mine;
    std::vector<const std::vector<VoxelSample>*> samples;
    for (size_t k = 0; k < occupied.size(); ++k)
        if (owner[k] == rank) {
            mine.push_back(occupied[k]);
            samples.push_back(&cells.byVoxel[occupied[k]]);
        }
    std::atomic<size_t> done{0};
    std::vector<VoxelTrainResult> trained = trainVoxels(mine, samples, start, [&] {
        const size_t d = ++done;
        if (progress.training) progress.training(double(d) / double(mine.size()));
    });
    result.voxels.assign(occupied.size(), VoxelTrainResult{});
    for (size_t k = 0, t = 0; k < occupied.size(); ++k) {
        result.voxels[k].voxel = occupied[k];  // (the others' too: a shard keeps their places)
        if (owner[k] == rank) result.voxels[k] = std::move(trained[t++]);
    }
    exchangeResults(group, owner, result.voxels);
    return owner;
}

// The asset of the networks as they stand (into result.asset).
void assembleAsset(const Scene& scene, const BakeSettings& settings, const BakeCells& cells, const format::Topology& topology,
                   BakeResult& result) {
    format::Asset& a = result.asset;
    a = format::Asset{};
    a.header.flags = format::kFlagScatteredRadiance;  // the training targets are L - Le (training_samples.h)
    if (settings.train.demodulate) a.header.flags |= format::kFlagDemodulated;  // ... over the reflectance (trainer.h)
    a.grid = cells.lattice;
    if (cells.band > 0.0f) {
        a.header.flags |= format::kFlagBlended;
        a.grid.blendBand = cells.band;
    }
    if (cells.adaptive) {
        a.header.flags |= format::kFlagTree;
        a.tree = result.partition.tree;
        a.leafCount = result.partition.leafCount;
    }
    a.topology = topology;
    for (const VoxelTrainResult& v : result.voxels) {
        a.voxels.push_back({v.voxel, v.scale});
        a.weights.insert(a.weights.end(), v.params.begin(), v.params.end());
    }
    for (const VoxelTrainResult& v : result.volume) {
        // format::kFlagVolumeExponential: the volume's networks decode exponentially (volumeNetworks' loss), whatever
        // the surfaces' topology says
        if (v.transform == format::OutputTransform::Exponential) a.header.flags |= format::kFlagVolumeExponential;
        a.volumeVoxels.push_back({v.voxel, v.scale});
        a.volumeWeights.insert(a.volumeWeights.end(), v.params.begin(), v.params.end());
    }
    for (const VoxelTrainResult& v : result.glossy) {
        a.glossyVoxels.push_back({v.voxel, v.scale});
        a.glossyWeights.insert(a.glossyWeights.end(), v.params.begin(), v.params.end());
    }
    if (settings.metadata) a.metadata = assetMetadata(scene, settings, result);
}

// The start of training within the integral equation as its generation 0.
GenerationStats startGeneration(const BakeSettings& settings, const BakeResult& result) {
    GenerationStats start;
    start.samples = result.sampleCount;
    start.rays = result.sampleStats.rays.total();
    start.samplingSeconds = result.timings.sampling;
    start.trainingSeconds = result.timings.training;
    for (const VoxelTrainResult& v : result.voxels) start.heldOutRelMse += v.heldOutRelMse / double(std::max<size_t>(1, result.voxels.size()));
    start.learningRate = settings.train.learningRate;
    return start;
}

// One round's fresh samples (into `fresh`), traced with the networks as the tail of their paths; returns them
// by cell (pointing into `fresh`).
std::vector<std::vector<VoxelSample>> roundSamples(const Scene& scene, const BakeTracing& tracing, const BakeCells& cells,
                                                   const eval::Partition& partition, const SampleSettings& round,
                                                   const TargetEstimator& estimator, std::vector<TrainingSample>& fresh,
                                                   GenerationStats& gs, BakeResult& result, const BakeGroup* group) {
    SampleStats stats;
    fresh = generateTrainingSamples(scene, tracing.tracer, tracing.grid, tracing.pieces, round, stats, {}, nullptr, estimator, group);
    gs.samples = fresh.size();
    gs.rays = stats.rays.total();
    result.sampleStats.rays += stats.rays;
    result.sampleStats.nonFinitePaths += stats.nonFinitePaths;
    result.sampleStats.hiddenSamples += stats.hiddenSamples;
    result.sampleCount += fresh.size();
    std::vector<uint32_t> ids(fresh.size());
    tbb::parallel_for(size_t(0), fresh.size(), [&](size_t i) {
        ids[i] = cells.adaptive ? cellOfPoint(partition, fresh[i].position) : fresh[i].voxel;
    });
    return samplesByNetwork(partition, ids, fresh, [&](size_t i) {
        return positionInCell(partition, result.partition, cells.adaptive, tracing.grid, fresh[i].position, ids[i]);
    });
}

// Training within the integral equation (paper Sec. 3): rounds of fresh points whose targets are a bounce or
// two with the networks as they stood for the rest of the path, each network continuing from where it was.
// Targets of a round come from the networks before it (frozen while it is sampled), and every network trains
// on its own samples, so the result does not depend on the threads. With a group, each process traces its share
// of a round's points and continues its own networks (the owners of the start), and the networks are exchanged
// after every round.
void integralRounds(const Scene& scene, const BakeSettings& settings, const BakeTracing& tracing, const BakeCells& cells,
                    const format::Topology& topology, const BakeProgress& progress, BakeResult& result, const BakeGroup* group) {
    const IntegralSettings& in = settings.integral;
    const eval::Partition partition = cellPartition(cells, result.partition);
    result.generations.push_back(startGeneration(settings, result));
    if (progress.generation) {
        assembleAsset(scene, settings, cells, topology, result);
        progress.generation(0, result);
    }
    NetworkField field(partition, topology, topology.outputTransform, settings.train.demodulate);
    std::vector<NetworkState> states(result.voxels.size());
    std::vector<double> costs;
    for (const VoxelTrainResult& v : result.voxels) costs.push_back(double(cells.byVoxel[v.voxel].size()));
    const std::vector<int> owner = networkOwners(costs, group);  // the start's owners (trainCells)
    const int rank = group ? group->rank() : 0;
    for (size_t k = 0; k < states.size(); ++k) {
        field.set(result.voxels[k].voxel, result.voxels[k].params, result.voxels[k].scale);
        states[k].result = result.voxels[k];
    }
    const ScatteredRadiance tail = [&field](const SurfaceInteraction& si) { return field.scattered(si); };
    SampleSettings round = settings.samples;
    round.points = in.points > 0 ? in.points : roundPoints(states.size());
    round.paths = std::max(1u, in.paths);
    round.firstPoint = settings.samples.points;
    const TargetEstimator estimator{&tail, std::max(1, in.bounces)};
    for (uint32_t g = 1; g <= in.generations; ++g) {
        GenerationStats gs;
        gs.generation = g;
        const float f = in.generations > 1 ? float(g - 1) / float(in.generations - 1) : 1.0f;
        gs.learningRate = exponentialDecay(in.learningRate, in.finalLearningRate / in.learningRate, f);
        round.generation = g;
        auto ts = std::chrono::steady_clock::now();
        std::vector<TrainingSample> fresh;
        const std::vector<std::vector<VoxelSample>> byCell =
            roundSamples(scene, tracing, cells, partition, round, estimator, fresh, gs, result, group);
        round.firstPoint += round.points;
        gs.samplingSeconds = since(ts);
        auto tt = std::chrono::steady_clock::now();
        tbb::parallel_for(tbb::blocked_range<size_t>(0, states.size(), 1), [&](const tbb::blocked_range<size_t>& r) {
            for (size_t k = r.begin(); k != r.end(); ++k) {
                const std::vector<VoxelSample>& mine = byCell[states[k].result.voxel];
                if (owner[k] == rank && !mine.empty())
                    continueVoxel(mine, settings.train, g, in.epochs, gs.learningRate, in.averageDecay, states[k]);
            }
        });
        if (group && group->size() > 1) {
            std::vector<VoxelTrainResult> now(states.size());
            for (size_t k = 0; k < states.size(); ++k)
                if (owner[k] == rank) now[k] = states[k].result;
            exchangeResults(group, owner, now);
            for (size_t k = 0; k < states.size(); ++k)
                if (owner[k] != rank) states[k].result = std::move(now[k]);
        }
        for (size_t k = 0; k < states.size(); ++k) {
            field.set(states[k].result.voxel, states[k].result.params, states[k].result.scale);
            gs.heldOutRelMse += states[k].result.heldOutRelMse / double(states.size());
        }
        gs.trainingSeconds = since(tt);
        result.timings.sampling += gs.samplingSeconds;
        result.timings.training += gs.trainingSeconds;
        result.generations.push_back(gs);
        if (progress.generation) {
            for (size_t k = 0; k < states.size(); ++k) result.voxels[k] = states[k].result;
            assembleAsset(scene, settings, cells, topology, result);
            progress.generation(g, result);
        }
    }
    for (size_t k = 0; k < states.size(); ++k) result.voxels[k] = states[k].result;
}

}  // namespace

format::Topology bakeTopology(const BakeSettings& settings) {
    format::Topology topology;
    topology.hiddenWidths.assign(settings.train.shape.hidden.begin(), settings.train.shape.hidden.end());
    topology.weightEncoding = settings.encoding;
    topology.outputTransform = exponentialOutput(settings.train.loss) ? format::OutputTransform::Exponential : format::OutputTransform::ClampedLinear;
    return topology;
}

BakeSettings resolvedBakeSettings(BakeSettings s) {
    SampleSettings& ss = s.samples;
    const bool integral = s.training == TrainingMethod::Integral;
    if (ss.paths == 0) ss.paths = integral ? kIntegralStartPaths : kMonteCarloPaths;
    if (ss.points > 0) return s;
    const uint64_t cells = uint64_t(s.grid.x) * s.grid.y * s.grid.z;
    uint64_t points = 0;
    if (s.partition.budgetBytes > 0) {
        const format::Topology t = bakeTopology(s);
        // With the volume's networks the budget pays for two or three networks per leaf: as many times fewer leaves.
        const uint64_t networks = s.partition.budgetBytes / ((1 + volumeSets(s)) * (t.parameterCount() * t.bytesPerWeight() + 40));
        points = std::clamp<uint64_t>(networks * kPointsPerNetwork, kBasePoints, kMaxAutomaticPoints);
    } else if (integral) {
        points = std::clamp<uint64_t>(kIntegralPointsPerCell * cells, kIntegralMinPoints, kMaxAutomaticPoints);
    } else {
        points = std::clamp<uint64_t>(kBasePoints * cells / 27, kBasePoints, kMaxAutomaticPoints);
    }
    ss.points = uint32_t(points);
    return s;
}

const SampleSettings& defaultBakeSamples() {
    static const BakeSettings s = resolvedBakeSettings(BakeSettings());
    return s.samples;
}

namespace {

// The processes the phases after sampling run with (partition, train, rounds, assemble), every mode's: `partition`
// those that share the partition's scoring, `training` those that train the networks together; nullptr: this
// process alone. (Sampling takes its own: samplePhase.)
struct BakeGroups {
    const BakeGroup *partition = nullptr, *training = nullptr;
};

// The plan: the scene's BVH, lights, grid and surface pieces (the time into result).
std::unique_ptr<BakeTracing> setupPhase(const Scene& scene, const BakeSettings& settings, BakeResult& result) {
    auto t0 = std::chrono::steady_clock::now();
    auto tracing = std::make_unique<BakeTracing>(scene, settings);
    result.surfaceArea = tracing->pieces.totalArea();
    result.timings.setup = since(t0);
    return tracing;
}

// A shard's settings, resolved: Monte Carlo training only.
BakeSettings shardSettings(const BakeSettings& given) {
    const BakeSettings settings = resolvedBakeSettings(given);
    if (settings.training == TrainingMethod::Integral) throw std::invalid_argument(kShardsNotIntegral);
    return settings;
}

// The training samples (their counts and time into result).
std::vector<TrainingSample> samplePhase(const Scene& scene, const BakeSettings& settings, BakeTracing& tracing, const BakeProgress& progress,
                                        BakeResult& result, const BakeGroup* group) {
    auto t1 = std::chrono::steady_clock::now();
    std::vector<TrainingSample> samples = generateTrainingSamples(scene, tracing.tracer, tracing.grid, tracing.pieces, settings.samples,
                                                                  result.sampleStats, progress.sampling, &tracing.selector, {}, group);
    result.sampleCount = samples.size();
    result.timings.sampling = since(t1);
    return samples;
}

// The volume's networks (BakeSettings::volume), or with `glossy` its glossy response's: samples in every cell's free
// space, one network per cell that has any, trained as the surfaces' are. Every process of a group computes them whole.
std::vector<VoxelTrainResult> volumeNetworks(const BakeSettings& settings, const BakeTracing& tracing, const BakeCells& cells,
                                             BakeResult& result, bool glossy) {
    const eval::Partition partition = cellPartition(cells, result.partition);
    VolumeSettings volume = settings.volume;  // its noisy targets' paths as the surfaces'
    volume.extraPathsFactor = settings.samples.extraPathsFactor;
    volume.noisyRelativeError = settings.samples.noisyRelativeError;
    const std::vector<TrainingSample> samples = generateVolumeSamples(tracing.tracer, partition, volume, settings.samples.seed,
                                                                      settings.samples.maxDepth, glossy ? result.glossyStats : result.volumeStats, glossy);
    std::vector<uint32_t> cellOf(samples.size());
    for (size_t i = 0; i < samples.size(); ++i) cellOf[i] = samples[i].voxel;
    const std::vector<std::vector<VoxelSample>> byCell = samplesByNetwork(partition, cellOf, samples, [&](size_t i) {
        return positionInCell(partition, result.partition, cells.adaptive, tracing.grid, samples[i].position, cellOf[i]);
    });
    std::vector<uint32_t> occupied;
    std::vector<const std::vector<VoxelSample>*> lists;
    for (uint32_t c = 0; c < uint32_t(byCell.size()); ++c)
        if (!byCell[c].empty()) {
            occupied.push_back(c);
            lists.push_back(&byCell[c]);
        }
    // A cell's irradiance spans the emitters' full radiance to the dark corners' indirect light: the surfaces'
    // relative loss (its scale the prediction's alone) lets a network hold dark targets bright at a bounded cost,
    // and in the Cornell box's light cell it did (held-out relMSE 3); the symmetric one weighs the target too, and
    // through an exponential output at a tenth of the cell's mean the network spans that range as ratios (in a
    // refit of the Cornell box's cells, held-out relMSE 1.5-2.8x below the linear output's). Not the glossy
    // response's: its targets (a sharp lobe's reflection of the lights) stay noisy after the extra paths, and a
    // loss scaled by the target fits noisy targets low (the Cornell box's glossy spheres at 0.12-0.28 of the
    // reference's mean).
    TrainSettings train = settings.train;
    if (train.loss == LossKind::RelativeL2 && !glossy) train.loss = LossKind::SymmetricRelativeExp;
    return trainVoxels(occupied, lists, train);
}

void volumePhase(const BakeSettings& settings, const BakeTracing& tracing, const BakeCells& cells, BakeResult& result) {
    const auto t0 = std::chrono::steady_clock::now();
    result.volume = volumeNetworks(settings, tracing, cells, result, false);
    if (settings.volume.glossy) result.glossy = volumeNetworks(settings, tracing, cells, result, true);
    result.timings.volume = since(t0);
}

// The bake from its samples on: partition, training, rounds, the asset; returns each network's trainer.
std::vector<int> trainPhases(const Scene& scene, const BakeSettings& settings, const BakeTracing& tracing,
                             const std::vector<TrainingSample>& samples, const BakeProgress& progress, const BakeGroups& groups,
                             BakeResult& result) {
    const format::Topology topology = bakeTopology(settings);
    auto tPartition = std::chrono::steady_clock::now();
    const BakeCells cells = partitionCells(scene, settings, tracing.grid, samples, topology, progress, result, groups.partition);
    result.timings.partition = since(tPartition);

    auto t2 = std::chrono::steady_clock::now();
    const std::vector<int> owner = trainCells(settings, cells, progress, result, groups.training);
    result.timings.training = since(t2);
    if (settings.training == TrainingMethod::Integral)
        integralRounds(scene, settings, tracing, cells, topology, progress, result, groups.training);

    if (settings.volume.enabled) volumePhase(settings, tracing, cells, result);
    // A shard's asset holds only its networks: the others' places are zero (mergeNetworkParts fills them).
    for (VoxelTrainResult& v : result.voxels)
        if (v.params.empty()) v.params.assign(topology.parameterCount(), 0.0f);
    assembleAsset(scene, settings, cells, topology, result);
    if (cells.budgeted) {
        const format::Asset& a = result.asset;
        const uint64_t bytes =
            format::encodedSize(a.topology, a.voxels.size(), a.tree.size(), a.metadata.size(), a.volumeVoxels.size(), a.glossyVoxels.size());
        if (a.metadata.size() > cells.reserve.bytes(a.voxels.size()) || bytes > settings.partition.budgetBytes)
            throw std::logic_error("the adaptive asset's " + std::to_string(bytes) + " bytes exceed the budget of " +
                                   std::to_string(settings.partition.budgetBytes));
    }
    return owner;
}

}  // namespace

BakeResult bakeScene(const Scene& scene, const BakeSettings& given, const BakeProgress& progress, const BakeGroup* group) {
    const BakeSettings settings = resolvedBakeSettings(given);
    BakeResult result;
    const std::unique_ptr<BakeTracing> tracing = setupPhase(scene, settings, result);
    const std::vector<TrainingSample> samples = samplePhase(scene, settings, *tracing, progress, result, group);
    trainPhases(scene, settings, *tracing, samples, progress, {group, group}, result);
    return result;
}

std::vector<std::vector<uint8_t>> traceShard(const Scene& scene, const BakeSettings& given, ShardId shard, const BakeProgress& progress,
                                             BakeResult* stats) {
    const BakeSettings settings = shardSettings(given);
    BakeResult result;
    const std::unique_ptr<BakeTracing> tracing = setupPhase(scene, settings, result);
    ShardGroup group(shard, {});
    samplePhase(scene, settings, *tracing, progress, result, &group);
    if (stats) *stats = std::move(result);
    return group.recorded();
}

BakeResult bakeShard(const Scene& scene, const BakeSettings& given, const ShardGroup& group, const BakeProgress& progress,
                     std::vector<uint32_t>& trained) {
    const BakeSettings settings = shardSettings(given);
    BakeResult result;
    const std::unique_ptr<BakeTracing> tracing = setupPhase(scene, settings, result);
    // Without stage-1 parts this shard traces every point itself; the partition it computes alone (as every shard
    // does); the networks it trains are its share, recorded by the group instead of exchanged.
    std::vector<TrainingSample> samples;
    try {
        samples = samplePhase(scene, settings, *tracing, progress, result, group.traces() ? nullptr : &group);
    } catch (const ShardPartError&) {
        throw;
    } catch (const std::runtime_error& e) {  // the parts' messages are not what this bake's tracing sends
        throw ShardPartError(std::string("the traced parts do not fit this bake (parts of another nrad build?): ") + e.what());
    }
    group.startRecording();
    const std::vector<int> owner = trainPhases(scene, settings, *tracing, samples, progress, {nullptr, &group}, result);
    trained.clear();
    for (size_t k = 0; k < owner.size(); ++k)
        if (owner[k] == group.rank()) trained.push_back(uint32_t(k));
    return result;
}

std::string assetMetadata(const Scene& scene, const BakeSettings& settings, const BakeResult& result) {
    nlohmann::json j;
    j["tool"] = "nrad 0.1.0";
    char hash[17];
    std::snprintf(hash, sizeof hash, "%016llx", (unsigned long long)sceneHash(scene));
    j["scene_hash"] = hash;
    const SampleSettings& s = settings.samples;
    const TrainSettings& t = settings.train;
    const TrainSettings first = startTrainSettings(settings);  // the networks' first training (integral: its start)
    j["bake"] = {{"grid", {settings.grid.x, settings.grid.y, settings.grid.z}},
                 {"points", s.points},
                 {"paths", s.paths},
                 {"max_depth", s.maxDepth},
                 {"nee", neeModeName(settings.nee.mode)},
                 {"seed", s.seed},
                 {"min_samples_per_voxel", s.minSamplesPerVoxel},
                 {"hidden", t.shape.hidden},
                 {"epochs", t.epochs},
                 {"loss", lossName(t.loss)},
                 {"demodulated", t.demodulate},
                 {"blend_band", settings.blendBand},
                 {"weight_decays", t.weightDecays},
                 {"race_epochs", raced(first) ? first.raceEpochs : 0},
                 {"epoch_average", t.epochAverage},
                 {"environment", environmentMetadata(scene.environment)},
                 {"lighting", settings.lightingJson.empty() ? nlohmann::json::object() : nlohmann::json::parse(settings.lightingJson)}};
    if (settings.training == TrainingMethod::MonteCarlo && t.restarts != 1)
        j["bake"]["restarts"] = t.restarts;  // only then: assets of one start keep their bytes
    if (raced(first) && first.raceAll) j["bake"]["race_all"] = true;  // only then
    if (settings.training == TrainingMethod::Integral) {  // only then, so that Monte Carlo assets keep their bytes
        const IntegralSettings& in = settings.integral;
        j["bake"]["training"] = {{"method", trainingMethodName(settings.training)},
                                 {"generations", in.generations},
                                 {"points_per_generation", in.points > 0 ? in.points : roundPoints(result.voxels.size())},
                                 {"paths_per_point", in.paths},
                                 {"bounces", in.bounces},
                                 {"epochs_per_generation", in.epochs},
                                 {"learning_rate", {in.learningRate, in.finalLearningRate}},
                                 {"average_decay", in.averageDecay}};
        if (in.restarts() != 1) j["bake"]["training"]["start_restarts"] = in.restarts();  // only then: earlier assets keep their bytes
    }
    if (settings.volume.enabled)  // only then, so that other assets keep their bytes
        j["bake"]["volume"] = {{"points_per_cell", settings.volume.pointsPerCell}, {"paths", settings.volume.paths}};
    if (settings.volume.enabled && settings.volume.glossy)  // only then, so that other volume assets keep their bytes
        j["bake"]["volume"]["glossy_roughness"] = std::round(double(eval::kGlossyRoughness) * 1e6) / 1e6;  // 0.3, not 0.30000001
    if (settings.partition.budgetBytes > 0)  // only then, so that grid assets keep their bytes
        j["bake"]["partition"] = {{"kind", "kd-tree"},
                                  {"budget_bytes", settings.partition.budgetBytes},
                                  {"levels", settings.partition.levels},
                                  {"min_leaf_samples", settings.partition.minLeafSamples}};
    else if (result.partition.leafCount > 0)  // the grid split at walls (only then, so that grid assets keep their bytes)
        j["bake"]["partition"] = {{"kind", "grid-walls"},
                                  {"wall_min_gain", settings.walls.minGainPerSample},
                                  {"wall_splits", result.partition.leafCount - settings.grid.x * settings.grid.y * settings.grid.z}};
    nlohmann::json engine = nlohmann::json::array();
    for (size_t i = 0; i < scene.lights.size(); ++i)
        if (scene.lights[i].runtimeDirect) engine.push_back({{"light", i}, {"name", scene.lights[i].name}});
    // Mixed lighting: the punctual lights whose direct light the engine must add (the asset holds only their
    // indirect light). Empty: the asset holds all the scattered light.
    j["engine_drawn_direct"] = engine;
    j["samples"] = result.sampleCount;
    // Held-out relMSE per occupied voxel, in VOXL order, rounded to 1e-6 (not in budgeted assets, whose bytes go to
    // networks: their --stats hold it).
    if (settings.partition.budgetBytes == 0) {
        std::vector<double> err;
        for (const VoxelTrainResult& v : result.voxels) err.push_back(std::round(v.heldOutRelMse * 1e6) / 1e6);
        j["held_out_relmse"] = err;
    }
    return j.dump();
}

}  // namespace nrad
