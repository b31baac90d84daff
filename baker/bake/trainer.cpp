// The training pieces every bake shares (samples per network, a network's prepared samples, its error as shaded, the
// checks after training) and the rounds of training within the integral equation (continueVoxel); the Monte Carlo
// training of the voxels runs in lockstep lanes (trainer_lockstep.cpp).
#include "baker/bake/trainer.h"
#include "baker/bake/training_parts.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <memory>
#include <numeric>

#include <tbb/parallel_for.h>

#include "baker/nn/schedule.h"
#include "baker/render/sampler.h"
#include "baker/util/maths.h"

namespace nrad {

glm::vec3 decodeOutput(format::OutputTransform transform, float scale, const float y[3]) {
    float rgb[3];
    eval::decodeOutputs(transform, scale, y, rgb);
    return glm::vec3(rgb[0], rgb[1], rgb[2]);
}

double relativeSquaredError(const glm::vec3& prediction, const glm::vec3& reference) {
    return relMse(prediction, reference);
}

std::vector<std::vector<VoxelSample>> samplesByNetwork(const eval::Partition& partition, const std::vector<uint32_t>& cellOfSample,
                                                       const std::vector<TrainingSample>& samples,
                                                       const std::function<glm::vec3(size_t)>& ownPosition) {
    std::vector<std::vector<VoxelSample>> out(size_t(partition.cells));
    std::vector<uint8_t> occupied(size_t(partition.cells), 0);
    for (uint32_t c : cellOfSample) occupied[c] = 1;
    // Every sample's supports in parallel, then gathered per network in the samples' order; in chunks, since a
    // sample's supports take 200 bytes (all of zdm2's 3.9 M at once were 780 MB, most of the bake's peak memory).
    struct Found {
        int count;
        eval::Support sup[eval::kMaxSupports];
    };
    constexpr size_t kChunk = size_t(1) << 16;
    std::vector<Found> found(std::min(kChunk, samples.size()));
    for (size_t c0 = 0; c0 < samples.size(); c0 += kChunk) {
        const size_t c1 = std::min(samples.size(), c0 + kChunk);
        tbb::parallel_for(tbb::blocked_range<size_t>(c0, c1, 1024), [&](const tbb::blocked_range<size_t>& range) {
            for (size_t i = range.begin(); i != range.end(); ++i) {
                const float p[3] = {samples[i].position.x, samples[i].position.y, samples[i].position.z};
                Found& f = found[i - c0];
                f.count = partition.supports(p, f.sup);
                f.count = eval::keepOccupied(f.sup, f.count, [&](int64_t v) { return occupied[size_t(v)] != 0; });
            }
        });
        for (size_t i = c0; i < c1; ++i) {
            const TrainingSample& s = samples[i];
            const Found& f = found[i - c0];
            for (int k = 0; k < f.count; ++k)
                out[size_t(f.sup[k].voxel)].push_back({&s, f.sup[k].weight, glm::vec3(f.sup[k].local[0], f.sup[k].local[1], f.sup[k].local[2])});
            if (f.count == 0)  // rounded just outside the box (training_samples.cpp keeps its piece's voxel): its own cell
                out[cellOfSample[i]].push_back({&s, 1.0f, ownPosition(i)});
        }
    }
    // Without the slack of the pushes (about 40 MB of zdm2's 166 MB of supports).
    for (std::vector<VoxelSample>& cell : out) cell.shrink_to_fit();
    return out;
}

std::vector<std::vector<VoxelSample>> samplesByNetwork(const VoxelGrid& grid, float band, const std::vector<TrainingSample>& samples) {
    std::vector<uint32_t> own(samples.size());
    for (size_t i = 0; i < samples.size(); ++i) own[i] = samples[i].voxel;
    return samplesByNetwork(eval::Partition(grid.grid(), band, {}, 0), own, samples,
                            [&](size_t i) { return grid.positionInVoxel(samples[i].position, samples[i].voxel); });
}

VoxelTrainResult trainVoxel(const VoxelGrid& grid, uint32_t voxel, const std::vector<const TrainingSample*>& samples,
                            const TrainSettings& settings) {
    std::vector<VoxelSample> v;
    v.reserve(samples.size());
    for (const TrainingSample* s : samples) v.push_back({s, 1.0f, grid.positionInVoxel(s->position, voxel)});
    return trainVoxel(voxel, v, settings);
}

namespace trainer_detail {

PreparedSamples prepareSamples(uint32_t voxel, const std::vector<VoxelSample>& entries, const TrainSettings& settings, uint32_t salt) {
    PreparedSamples d;
    d.entries = &entries;
    const size_t n = entries.size();
    const int nIn = settings.shape.inputs;
    d.inputs.resize(n * size_t(nIn));
    d.targets.resize(n);
    d.modulation.assign(n, glm::vec3(1.0f));
    d.weights.assign(n, glm::vec3(1.0f));
    uint32_t splitSeed = hashCombine(hashCombine(settings.seed, 0x73706c74u), voxel);
    if (salt != 0) splitSeed = hashCombine(splitSeed, salt);
    for (size_t i = 0; i < n; ++i) {
        const TrainingSample& t = *entries[i].sample;
        const float local[3] = {entries[i].local.x, entries[i].local.y, entries[i].local.z};
        const float normal[3] = {t.normal.x, t.normal.y, t.normal.z}, direction[3] = {t.wo.x, t.wo.y, t.wo.z};
        eval::encodeInputs(local, normal, direction, &d.inputs[i * size_t(nIn)]);
        d.targets[i] = t.radiance;
        if (settings.demodulate) {
            // The network learns radiance / reflectance (floored); a channel whose reflectance is below the
            // floor weighs (R / floor)^2 in the loss: black has nothing to learn and is left free.
            const glm::vec3 r = t.reflectance, div = demodulationDivisor(t);
            d.targets[i] /= div;
            d.modulation[i] = r;
            d.weights[i] = (r / div) * (r / div);
        }
        d.weights[i] *= entries[i].weight;
        bool hold = float(hashCombine(splitSeed, uint32_t(i)) >> 8) * 0x1p-24f < settings.holdoutFraction;
        (hold ? d.heldOut : d.train).push_back(i);
    }
    if (d.train.empty() && !d.heldOut.empty()) {
        d.train.push_back(d.heldOut.back());
        d.heldOut.pop_back();
    }
    if (d.heldOut.empty() && d.train.size() >= 2) {
        d.heldOut.push_back(d.train.back());
        d.train.pop_back();
    }
    return d;
}

// One pass over `perm` in mini-batches (batch-major kernels): the loss's gradient, averaged over the batch, plus
// an L2 penalty of weightDecay / (training samples) on every parameter but the output biases, one Adam step
// per batch; average (if given): after every step, average = decay average + (1 - decay) parameters.
void trainEpoch(Mlp& mlp, Adam& adam, MlpBatchWorkspace& ws, const PreparedSamples& d, const std::vector<size_t>& perm,
                const TrainSettings& settings, float invScale, float lr, float weightDecay, std::vector<float>* average = nullptr,
                float decay = 0.0f) {
    const int nIn = settings.shape.inputs, nOut = settings.shape.outputs;
    const size_t L = mlp.layers();
    const size_t batch = size_t(std::clamp(settings.batchSize, 1, MlpBatchWorkspace::kMaxBatch));
    std::vector<float> grad(mlp.parameters().size()), x(batch * size_t(nIn));
    for (size_t b = 0; b < perm.size(); b += batch) {
        const size_t e = std::min(perm.size(), b + batch);
        const int count = int(e - b);
        std::fill(grad.begin(), grad.end(), 0.0f);
        for (size_t k = b; k < e; ++k)
            std::copy_n(&d.inputs[perm[k] * size_t(nIn)], nIn, &x[(k - b) * size_t(nIn)]);
        mlp.forwardBatch(x.data(), count, ws);
        for (int k = 0; k < count; ++k) {
            const size_t i = perm[b + size_t(k)];
            float y[3], dy[3];
            for (int c = 0; c < nOut; ++c) y[c] = ws.value(L, c)[k];
            const float t[3] = {lossTarget(settings.loss, invScale, d.targets[i][0]), lossTarget(settings.loss, invScale, d.targets[i][1]),
                                lossTarget(settings.loss, invScale, d.targets[i][2])};
            const float w[3] = {d.weights[i][0], d.weights[i][1], d.weights[i][2]};
            regressionGradient(settings.loss, y, t, w, dy);
            for (int c = 0; c < nOut; ++c) ws.delta(L, c)[k] = dy[c];
        }
        mlp.backwardBatch(ws, grad.data());
        float inv = 1.0f / float(count);
        for (float& g : grad) g *= inv;
        const float wd = weightDecay / float(std::max<size_t>(1, d.train.size()));
        if (wd > 0.0f)
            for (size_t q = 0; q + size_t(nOut) < grad.size(); ++q) grad[q] += wd * mlp.parameters()[q];
        adam.step(mlp.parameters(), grad, lr);
        if (average) updateAverage(*average, mlp.parameters(), decay);
    }
}

double shadedError(const Mlp& mlp, MlpBatchWorkspace& ws, const PreparedSamples& d, const std::vector<size_t>& set,
                   const TrainSettings& settings, format::OutputTransform transform, float scale) {
    // In batches through the mini-batch kernels (the same outputs as the per-sample pass, bit for bit).
    const size_t nIn = size_t(settings.shape.inputs), L = mlp.layers(), B = MlpBatchWorkspace::kMaxBatch;
    float x[MlpBatchWorkspace::kMaxBatch * eval::kInputs];
    double e = 0.0, w = 0.0;
    for (size_t b = 0; b < set.size(); b += B) {
        const size_t count = std::min(B, set.size() - b);
        for (size_t k = 0; k < count; ++k) std::copy_n(&d.inputs[set[b + k] * nIn], nIn, &x[k * nIn]);
        mlp.forwardBatch(x, int(count), ws);
        for (size_t k = 0; k < count; ++k) {
            const size_t i = set[b + k];
            const float y[3] = {ws.value(L, 0)[k], ws.value(L, 1)[k], ws.value(L, 2)[k]};
            e += double(d.blend(i)) * relativeSquaredError(d.modulation[i] * decodeOutput(transform, scale, y), d.sample(i).radiance);
            w += double(d.blend(i));
        }
    }
    return w > 0.0 ? e / w : 0.0;
}

bool greyTargets(const PreparedSamples& d) {
    for (const glm::vec3& t : d.targets) {
        const float m = (t.x + t.y + t.z) / 3.0f, tol = 1e-4f * std::abs(m);
        if (std::abs(t.x - m) > tol || std::abs(t.y - m) > tol || std::abs(t.z - m) > tol) return false;
    }
    return true;
}

void averageOutputs(std::vector<float>& params, const NetworkShape& shape) {
    const size_t nOut = size_t(shape.outputs), in = size_t(shape.hidden.back()), n = params.size();
    float* W = &params[n - nOut - nOut * in];
    float* b = &params[n - nOut];
    for (size_t j = 0; j < in; ++j) {
        float m = 0.0f;
        for (size_t o = 0; o < nOut; ++o) m += W[o * in + j];
        m /= float(nOut);
        for (size_t o = 0; o < nOut; ++o) W[o * in + j] = m;
    }
    float mb = 0.0f;
    for (size_t o = 0; o < nOut; ++o) mb += b[o];
    mb /= float(nOut);
    for (size_t o = 0; o < nOut; ++o) b[o] = mb;
}

std::string attemptFailure(const Mlp& mlp, const PreparedSamples& d, const std::vector<size_t>& train, const TrainSettings& settings,
                           float invScale, bool nonFinite) {
    if (nonFinite) return "non-finite weights or error";
    if (train.empty()) return {};
    const int nIn = settings.shape.inputs, width = settings.shape.hidden.front();
    MlpWorkspace ws;
    std::vector<float> y(static_cast<size_t>(settings.shape.outputs));
    std::vector<bool> alive(size_t(width), false);
    glm::dvec3 mean(0.0), mean2(0.0), tmean(0.0), tmean2(0.0);
    for (size_t i : train) {
        mlp.forward(&d.inputs[i * size_t(nIn)], y.data(), ws);
        for (int u = 0; u < width; ++u)
            if (ws.activations(1)[u] > 0.0f) alive[size_t(u)] = true;
        glm::dvec3 p(y[0], y[1], y[2]);
        glm::dvec3 t(lossTarget(settings.loss, invScale, d.targets[i][0]), lossTarget(settings.loss, invScale, d.targets[i][1]),
                     lossTarget(settings.loss, invScale, d.targets[i][2]));
        mean += p;
        mean2 += p * p;
        tmean += t;
        tmean2 += t * t;
    }
    double m = double(train.size());
    double predVar = glm::dot(mean2 / m - (mean / m) * (mean / m), glm::dvec3(1.0));
    double targetVar = glm::dot(tmean2 / m - (tmean / m) * (tmean / m), glm::dvec3(1.0));
    if (std::none_of(alive.begin(), alive.end(), [](bool a) { return a; })) return "all hidden ReLUs dead";
    if (train.size() >= 8 && targetVar > 1e-4 && predVar < 1e-8 * targetVar) return "constant output";
    return {};
}

}  // namespace trainer_detail

using namespace trainer_detail;

// Optimizer steps of one network in one round of integral training at the full rate (about twice what a network's
// 2,000 samples x 4 passes take in batches of 32).
constexpr double kRoundSteps = 512.0;

VoxelTrainResult continueVoxel(const std::vector<VoxelSample>& entries, const TrainSettings& settings, uint32_t generation, int epochs,
                               float learningRate, float averageDecay, NetworkState& state) {
    auto start = std::chrono::steady_clock::now();
    VoxelTrainResult& result = state.result;
    const PreparedSamples d = prepareSamples(result.voxel, entries, settings, generation);
    const float invScale = 1.0f / result.scale;
    Mlp mlp(settings.shape);
    if (state.params.empty()) state.params = result.params;
    mlp.parameters() = state.params;
    MlpBatchWorkspace bws;
    if (!state.adam) state.adam = std::make_unique<Adam>(mlp.parameters().size());
    std::vector<float> average = result.params;
    SplitMix64 order((uint64_t(settings.seed) << 32) ^ (uint64_t(result.voxel) << 8) ^ (uint64_t(generation) << 40) ^ 0x9e3779b97f4a7c15ull);
    std::vector<size_t> perm = d.train;
    // A round of more steps than kRoundSteps takes smaller ones and averages over more of them, in proportion:
    // what a network moves per round (and the noise it keeps) does not grow with its samples (at the full rate,
    // large rounds drifted: docs/design.md).
    const size_t batch = size_t(std::clamp(settings.batchSize, 1, MlpBatchWorkspace::kMaxBatch));
    const double steps = double(epochs) * double((perm.size() + batch - 1) / batch);
    const float scale = steps > kRoundSteps ? float(kRoundSteps / steps) : 1.0f;
    const float rate = learningRate * scale, decay = 1.0f - (1.0f - averageDecay) * scale;
    for (int epoch = 0; epoch < epochs; ++epoch) {
        for (size_t i = perm.size(); i > 1; --i) std::swap(perm[i - 1], perm[size_t(order.below(i))]);
        trainEpoch(mlp, *state.adam, bws, d, perm, settings, invScale, rate, result.weightDecay, averageDecay > 0.0f ? &average : nullptr,
                   decay);
    }
    // Kept only if finite; a network that diverged keeps what it had (and says so).
    const bool finite = mlp.allFinite() && std::all_of(average.begin(), average.end(), [](float v) { return std::isfinite(v); });
    if (finite) {
        state.params = mlp.parameters();
        result.params = averageDecay > 0.0f ? average : mlp.parameters();
    } else {
        result.events.push_back("generation " + std::to_string(generation) + ": non-finite weights, update dropped");
        state.adam = std::make_unique<Adam>(mlp.parameters().size());
        state.params = result.params;
    }
    mlp.parameters() = result.params;
    result.trainCount += d.train.size();
    result.heldOutCount = d.heldOut.size();
    result.heldOutRelMse = shadedError(mlp, bws, d, d.evalSet(), settings, result.transform, result.scale);
    result.trainRelMse = shadedError(mlp, bws, d, d.train, settings, result.transform, result.scale);
    result.epochs += epochs;
    result.seconds += std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    result.curve.push_back({int(generation), result.seconds, result.heldOutRelMse});
    return result;
}

}  // namespace nrad
