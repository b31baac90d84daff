// Training the voxels' networks, many at once: every training (a voxel's network under one weight decay, from one
// initialisation) is a job that runs in one lane of networks trained in lockstep (baker/nn/mlp_lockstep.h), eight
// or sixteen to a register (the kernel's lanes); a lane whose job ends takes the next. Each job keeps its own
// schedule: its samples' order, its learning rate and Adam's step count, its held-out error after every epoch,
// early stopping, re-initialisation after a failed attempt and the constant fallback (trainer.h). A lane's
// arithmetic never meets another lane's, so a job's result is the same whichever lane, group, thread or kernel
// runs it and whatever runs beside it.
#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <limits>
#include <memory>
#include <mutex>
#include <new>
#include <stdexcept>
#include <utility>

#include <tbb/parallel_for.h>
#include <tbb/task_arena.h>

#include "baker/bake/trainer.h"
#include "baker/bake/training_parts.h"
#include "baker/nn/mlp_lockstep.h"
#include "baker/nn/random.h"
#include "baker/nn/schedule.h"
#include "baker/util/maths.h"

namespace nrad {

using namespace trainer_detail;

namespace {

using Clock = std::chrono::steady_clock;

double secondsSince(Clock::time_point t) { return std::chrono::duration<double>(Clock::now() - t).count(); }

// Storage that starts on a cache line (64 bytes), so that each packed sample is one line, not two.
static_assert(kPackedFloats * sizeof(float) == 64, "a packed sample is a cache line");
template <class T>
struct CacheLineAllocator {
    using value_type = T;
    CacheLineAllocator() = default;
    template <class U>
    CacheLineAllocator(const CacheLineAllocator<U>&) {}
    T* allocate(size_t n) { return static_cast<T*>(::operator new(n * sizeof(T), std::align_val_t(64))); }
    void deallocate(T* p, size_t) { ::operator delete(p, std::align_val_t(64)); }
    bool operator==(const CacheLineAllocator&) const { return true; }
    bool operator!=(const CacheLineAllocator&) const { return false; }
};

// What a voxel's candidates share, prepared once for all of them (and freed when the last of them ends): the
// samples packed for the lanes (64 bytes a sample), the held-out samples as each epoch's check reads them, the
// voxel's scale. Six candidates a voxel train at once in neighbouring lanes (a 1 MB zdm2 bake's largest voxels
// hold 30,000-67,000 samples).
struct VoxelData {
    std::vector<size_t> train;  // the training samples' indices (PreparedSamples::train)
    std::vector<float, CacheLineAllocator<float>> packed;  // a sample a cache line
    std::vector<float> heldOutInputs, heldOutTerms;
    size_t heldOutCount = 0;
    double weightSum = 0.0, heldOutWeight = 0.0;
    float scale = 1.0f, invScale = 1.0f;
    bool allZero = false;  // every target zero

    VoxelData(uint32_t voxel, const std::vector<VoxelSample>& entries, const TrainSettings& settings) {
        const PreparedSamples d = prepareSamples(voxel, entries, settings, 0);
        if (d.targets.size() >= size_t(UINT32_MAX)) throw std::length_error("a network's training samples number 2^32 or more");
        train = d.train;
        heldOutCount = d.heldOut.size();
        // Per-voxel scale: the mean training luminance (weighted), so that the network works with values near one
        // (a tenth of it for SymmetricRelativeExp, whose exp() then spans the dark end as a ratio).
        double meanLum = 0.0;
        for (size_t i : d.train) {
            meanLum += double(d.blend(i)) * std::max(0.0f, luminancef(d.targets[i]));
            weightSum += double(d.blend(i));
        }
        meanLum = weightSum > 0.0 ? meanLum / weightSum : 0.0;
        scale = meanLum > 1e-30 && std::isfinite(meanLum) ? float(meanLum) * scaleFraction(settings.loss) : 1.0f;
        invScale = 1.0f / scale;
        // Each sample packed for the lanes: inputs, loss targets, loss weights.
        const size_t nIn = size_t(settings.shape.inputs);
        packed.assign(d.targets.size() * kPackedFloats, 0.0f);
        for (size_t i = 0; i < d.targets.size(); ++i) {
            float* row = &packed[i * kPackedFloats];
            std::copy_n(&d.inputs[i * nIn], nIn, row);
            for (int c = 0; c < 3; ++c) {
                row[kPackedTarget + c] = lossTarget(settings.loss, invScale, d.targets[i][c]);
                row[kPackedWeight + c] = d.weights[i][c];
            }
        }
        // The held-out samples as each epoch's check reads them: inputs in a row, then per sample its blend weight,
        // reflectance, radiance and 1 / (radiance^2 + 0.01) per channel.
        for (size_t i : d.evalSet()) {
            heldOutInputs.insert(heldOutInputs.end(), &d.inputs[i * nIn], &d.inputs[i * nIn] + nIn);
            const glm::vec3 ref = d.sample(i).radiance;
            heldOutTerms.push_back(d.blend(i));
            for (int c = 0; c < 3; ++c) heldOutTerms.push_back(d.modulation[i][c]);
            for (int c = 0; c < 3; ++c) heldOutTerms.push_back(ref[c]);
            for (int c = 0; c < 3; ++c) heldOutTerms.push_back(float(1.0 / (double(ref[c]) * double(ref[c]) + 0.01)));
            heldOutWeight += double(d.blend(i));
        }
        allZero = !d.targets.empty() && std::all_of(d.targets.begin(), d.targets.end(), [](const glm::vec3& t) { return t == glm::vec3(0.0f); });
    }
};

// One training of a voxel's network with an L2 penalty of weightDecay / (training samples) on every parameter but
// the output biases, from the initialisation of `restart` (0: the first): attempts until one does not fail, each
// epochs of mini-batch steps in a lane, the parameters with the lowest held-out error kept.
class Training {
public:
    Training(uint32_t voxel, const std::vector<VoxelSample>& entries, std::shared_ptr<const VoxelData> data, const TrainSettings& settings,
             float weightDecay, int restart)
        : s_(settings), decay_(weightDecay), restart_(restart), voxel_(voxel), entries_(entries), data_(std::move(data)), mlp_(settings.shape) {
        result_.voxel = voxel;
        result_.transform = exponentialOutput(settings.loss) ? format::OutputTransform::Exponential : format::OutputTransform::ClampedLinear;
        result_.trainCount = data_->train.size();
        result_.heldOutCount = data_->heldOutCount;
        result_.weightDecay = weightDecay;
        result_.scale = data_->scale;
        batch_ = size_t(std::clamp(settings.batchSize, 1, MlpBatchWorkspace::kMaxBatch));
        // Nothing to learn where every target is zero (no light reaches the voxel's surfaces): the zero network, exact,
        // instead of a trained one's noise around zero.
        if (data_->allZero) {
            kept_.assign(mlp_.parameters().size(), 0.0f);
            finish();
            return;
        }
        if (settings.maxAttempts > 0) startAttempt();
        else finish();
    }

    bool done() const { return done_; }
    // Paused at the race's epoch (TrainSettings::raceEpochs), its lane's state saved in laneState(), until resume().
    bool parked() const { return parked_; }
    void resume() {
        parked_ = false;
        resumed_ = true;
    }
    // Whether the lane must take the saved state back (a resumed training); once.
    bool takeResumed() { return std::exchange(resumed_, false); }
    struct LaneState {
        std::vector<float> params, m, v;
    };
    LaneState& laneState() { return laneState_; }
    // What the race compares: the lowest held-out error of the epochs' checks so far (a fallback: none).
    double raceError() const { return done_ && result_.fallback ? std::numeric_limits<double>::infinity() : best_; }
    // Enter the race: pause after `epochs` epochs of the first attempt.
    void raceAt(int epochs) { raceAt_ = epochs; }
    double seconds() const { return done_ ? result_.seconds : seconds_; }
    // Whether the lane's parameters must be replaced by freshParams() (a new attempt began); once per attempt.
    bool takeFresh() { return std::exchange(fresh_, false); }
    const std::vector<float>& freshParams() const { return mlp_.parameters(); }
    // Whether the next thing to do is a step (else an epoch without samples ends at once: endEpoch).
    bool wantsStep() const { return !done_ && !parked_ && at_ < perm_.size(); }

    // This job's next mini-batch, as its lane's input.
    void fill(LockstepLane& lane) {
        lane.count = int(std::min(batch_, perm_.size() - at_));
        for (int k = 0; k < lane.count; ++k) lane.rows[k] = &data_->packed[size_t(perm_[at_ + size_t(k)]) * kPackedFloats];
        // The next batch's rows are fetched while this one trains: they lie scattered over the voxel's packed samples,
        // and with sixteen voxels training at once most are out of the core's caches (the step's gather of them took
        // a third of the step when they were not prefetched).
        const size_t next = at_ + size_t(lane.count), end = std::min(perm_.size(), next + batch_);
        for (size_t k = next; k < end; ++k) __builtin_prefetch(&data_->packed[size_t(perm_[k]) * kPackedFloats]);
        lane.learningRate = rate_;
        lane.weightDecay = decay_ / float(std::max<size_t>(1, result_.trainCount));
        beta1Power_ *= kAdamBeta1;
        beta2Power_ *= kAdamBeta2;
        lane.c1 = float(1.0 - beta1Power_);
        lane.c2 = float(1.0 - beta2Power_);
    }
    // After a step of `count` samples: whether the epoch is over (then endEpoch).
    bool stepped(int count, double seconds) {
        at_ += size_t(count);
        seconds_ += seconds;
        return at_ >= perm_.size();
    }
    // The epoch's held-out error of the lane's parameters (their average: averaged()), and what follows: the next epoch, the
    // next attempt or the end.
    void endEpoch(const std::vector<float>& params) {
        const Clock::time_point t0 = Clock::now();
        const std::vector<float>* judged = averaged(params);
        mlp_.parameters() = *judged;
        double err = 0.0;
        diverged_ = !mlp_.allFinite() || !std::isfinite(err = epochError());
        if (diverged_) return endAttempt(t0);
        if (epoch_ % std::max(1, s_.curveEvery) == 0) curve_.push_back({epoch_, seconds_, err});
        if (err < best_) {
            best_ = err;
            bestParams_ = *judged;
            sinceBest_ = 0;
        } else if (++sinceBest_ > s_.patience) {
            return endAttempt(t0);
        }
        if (++epoch_ >= s_.epochs) return endAttempt(t0);
        beginEpoch();
        if (epoch_ == raceAt_) {
            parked_ = true;
            raceAt_ = 0;
        }
        seconds_ += secondsSince(t0);
    }
    VoxelTrainResult takeResult() { return std::move(result_); }

private:
    // What the epoch's check judges and the training keeps: the moving average of the lane's parameters over the epochs
    // (TrainSettings::epochAverage, its decay min(D, (1 + e) / (10 + e)) at epoch e, from the first epoch's
    // parameters), or the parameters themselves.
    const std::vector<float>* averaged(const std::vector<float>& params) {
        const float limit = s_.epochAverage;
        if (!(limit > 0.0f)) return &params;
        if (epoch_ == 0) {
            average_ = params;
        } else {
            const float d = std::min(limit, float(1 + epoch_) / float(10 + epoch_)), e = 1.0f - d;
            for (size_t i = 0; i < params.size(); ++i) average_[i] = d * average_[i] + e * params[i];
        }
        return &average_;
    }
    double evaluate(const std::vector<size_t>& set) { return shadedError(mlp_, bws_, d_, set, s_, result_.transform, result_.scale); }
    // The held-out error of mlp_ as each epoch's check sees it: shadedError's (the weighted mean relMSE as shaded) to
    // rounding, its per-sample terms in float with the reciprocals taken once (shadedError's divisions in double cost
    // a sixth of the training), summed in double.
    double epochError() {
        constexpr size_t B = MlpBatchWorkspace::kMaxBatch, kTerms = 10;
        const size_t count = data_->heldOutTerms.size() / kTerms, nIn = size_t(s_.shape.inputs), L = mlp_.layers();
        double e = 0.0;
        for (size_t b = 0; b < count; b += B) {
            const int n = int(std::min(B, count - b));
            mlp_.forwardBatch(&data_->heldOutInputs[b * nIn], n, bws_);
            for (int k = 0; k < n; ++k) {
                const float* t = &data_->heldOutTerms[(b + size_t(k)) * kTerms];
                float sum = 0.0f;
                for (int c = 0; c < 3; ++c) {
                    const float diff = t[1 + c] * eval::decodeOutput(result_.transform, result_.scale, bws_.value(L, c)[k]) - t[4 + c];
                    sum += diff * diff * t[7 + c];
                }
                e += double(t[0]) * double(sum);
            }
        }
        return data_->heldOutWeight > 0.0 ? e / (3.0 * data_->heldOutWeight) : 0.0;
    }

    void startAttempt() {
        const int attempt = result_.attempts++;
        const uint64_t initSeed = (uint64_t(s_.seed) << 32) ^ (uint64_t(result_.voxel) << 8) ^ uint64_t(attempt) ^ (uint64_t(restart_) << 4);
        mlp_.initialize(initSeed, initialOutputBias(s_.loss));
        order_ = SplitMix64(initSeed ^ 0x5851f42d4c957f2dull);
        dropPrepared();
        perm_.assign(data_->train.begin(), data_->train.end());
        best_ = std::numeric_limits<double>::infinity();
        bestParams_ = mlp_.parameters();
        curve_.clear();
        sinceBest_ = 0;
        epoch_ = 0;
        diverged_ = false;
        beta1Power_ = beta2Power_ = 1.0;
        fresh_ = true;
        if (s_.epochs <= 0) return endAttempt(Clock::now());
        beginEpoch();
    }
    // The prepared samples are not read while the lanes train (they step on the shared packed samples and judge on
    // the shared held-out ones): they are prepared only when an attempt ends (the largest voxels of a 1 MB zdm2 bake
    // hold 30,000-67,000 samples each, 150 bytes a sample prepared, and a group of sixteen lanes trains the
    // sixteen largest at once).
    void dropPrepared() { d_ = PreparedSamples{}; }
    void prepareAgain() {
        if (!d_.entries) d_ = prepareSamples(voxel_, entries_, s_, 0);
    }
    void beginEpoch() {
        // order_.below(i) for each i, as the plain trainer draws it: a block's draws first (drawBelowDescending: they
        // do not depend on the order, eight at a time with AVX-512), then its swaps.
        uint32_t draw[64];
        for (size_t i = perm_.size(); i > 1;) {
            const uint32_t block = uint32_t(std::min<size_t>(64, i - 1));
            drawBelowDescending(order_, i, block, draw);
            for (uint32_t k = 0; k < block; ++k, --i) std::swap(perm_[i - 1], perm_[draw[k]]);
        }
        rate_ = exponentialDecay(s_.learningRate, 0.1f, float(epoch_) / float(std::max(1, s_.epochs)));
        at_ = 0;
    }
    void endAttempt(Clock::time_point t0) {
        prepareAgain();
        mlp_.parameters() = bestParams_;
        const std::string failure = attemptFailure(mlp_, d_, d_.train, s_, data_->invScale, diverged_ && !std::isfinite(best_));
        seconds_ += secondsSince(t0);
        if (failure.empty()) {
            result_.curve = std::move(curve_);
            result_.epochs = epoch_;
            kept_ = bestParams_;
            return finish();
        }
        result_.events.push_back("attempt " + std::to_string(result_.attempts) + ": " + failure + ", re-initialised");
        raceAt_ = 0;  // the race is run once, on the first attempt's epochs
        if (result_.attempts < s_.maxAttempts) return startAttempt();
        finish();
    }
    void finish() {
        const Clock::time_point t0 = Clock::now();
        prepareAgain();
        if (kept_.empty()) {
            // Every attempt failed: store a network that outputs the voxel's mean radiance, always finite.
            result_.fallback = true;
            result_.events.push_back("fallback: constant network with the voxel's mean radiance");
            std::fill(mlp_.parameters().begin(), mlp_.parameters().end(), 0.0f);
            glm::dvec3 mean(0.0);
            for (size_t i : d_.train) mean += double(d_.blend(i)) * glm::dvec3(d_.targets[i]);
            if (data_->weightSum > 0.0) mean /= data_->weightSum;
            const int nOut = s_.shape.outputs;
            const size_t outBias = mlp_.parameters().size() - size_t(nOut);
            for (int c = 0; c < nOut; ++c) mlp_.parameters()[outBias + size_t(c)] = lossTarget(s_.loss, data_->invScale, float(mean[c]));
            kept_ = mlp_.parameters();
        }
        mlp_.parameters() = kept_;
        result_.params = kept_;
        result_.heldOutRelMse = evaluate(d_.evalSet());
        result_.trainRelMse = evaluate(d_.train);
        result_.seconds = seconds_ + secondsSince(t0);
        done_ = true;
        fresh_ = false;
        // Only the result is read from here on, while the voxel's other candidates train: the samples' copies go
        // (150 bytes a sample; the largest voxels of a 1 MB zdm2 bake hold 30,000-67,000 samples each).
        d_ = PreparedSamples{};
        data_.reset();
        std::vector<float>().swap(average_);
        std::vector<uint32_t>().swap(perm_);
    }

    const TrainSettings& s_;
    float decay_;
    int restart_;
    uint32_t voxel_;
    const std::vector<VoxelSample>& entries_;
    std::shared_ptr<const VoxelData> data_;  // until the training ends
    PreparedSamples d_;  // only while an attempt ends (dropPrepared)
    Mlp mlp_;
    MlpBatchWorkspace bws_;
    VoxelTrainResult result_;
    std::vector<float> bestParams_, kept_, average_;
    std::vector<uint32_t> perm_;  // the epoch's order of the training samples (fewer than 2^32: VoxelData checks)
    std::vector<TrainCurvePoint> curve_;
    LaneState laneState_;
    SplitMix64 order_{0};
    double best_ = 0.0, beta1Power_ = 1.0, beta2Power_ = 1.0, seconds_ = 0.0;
    float rate_ = 0.0f;
    size_t batch_ = 1, at_ = 0;
    int epoch_ = 0, sinceBest_ = 0, raceAt_ = 0;
    bool diverged_ = false, fresh_ = false, done_ = false, parked_ = false, resumed_ = false;
};

// The candidates of one voxel (its trainings, in weight-decay then restart order) made into its result: the lowest
// held-out error wins (the first on a tie; a fallback only if every candidate fell back), grey where every target is.
VoxelTrainResult chooseCandidate(std::vector<VoxelTrainResult>& candidates, const std::vector<VoxelSample>& entries,
                                 const TrainSettings& settings) {
    VoxelTrainResult best;
    double seconds = 0.0;
    for (VoxelTrainResult& r : candidates) {
        seconds += r.seconds;
        const bool better = best.params.empty() || (best.fallback && !r.fallback) ||
                            (best.fallback == r.fallback && r.heldOutRelMse < best.heldOutRelMse);
        if (better) best = std::move(r);
    }
    if (settings.greyWhereGrey && !best.params.empty()) {
        // After the choice (which stays the one made on the channels): grey where every target is.
        const PreparedSamples d = prepareSamples(best.voxel, entries, settings, 0);
        if (greyTargets(d)) {
            averageOutputs(best.params, settings.shape);
            Mlp mlp(settings.shape);
            mlp.parameters() = best.params;
            MlpBatchWorkspace bws;
            best.heldOutRelMse = shadedError(mlp, bws, d, d.evalSet(), settings, best.transform, best.scale);
            best.trainRelMse = shadedError(mlp, bws, d, d.train, settings, best.transform, best.scale);
        }
    }
    best.seconds = seconds;
    return best;
}

// The trainings of one trainVoxels call: the jobs (the voxels with the most samples first, so that the longest
// trainings start first and the tail is short; a voxel's candidates consecutive, in weight-decay then restart
// order), each voxel's candidates as they end or pause at the race, the race's winners waiting for a lane, and
// the results. Groups of lanes (runGroup, one per thread) take trainings until none is left.
class LaneScheduler {
public:
    LaneScheduler(const std::vector<uint32_t>& voxels, const std::vector<const std::vector<VoxelSample>*>& samples,
                  const TrainSettings& settings, const std::function<void()>& onDone)
        : voxels_(voxels), samples_(samples), settings_(settings), onDone_(onDone), candidates_(voxels.size()), out_(voxels.size()) {
        const std::vector<float> none = {0.0f};
        const std::vector<float>& decays = settings.weightDecays.empty() ? none : settings.weightDecays;
        const size_t restarts = size_t(std::max(1, settings.restarts)), perVoxel = decays.size() * restarts;
        raceGroup_ = raceGroup(settings);
        racing_ = raced(settings);
        std::vector<size_t> order(voxels.size());
        for (size_t k = 0; k < order.size(); ++k) order[k] = k;
        std::stable_sort(order.begin(), order.end(), [&](size_t a, size_t b) { return samples[a]->size() > samples[b]->size(); });
        for (size_t k : order)
            for (size_t d = 0; d < decays.size(); ++d)
                for (size_t restart = 0; restart < restarts; ++restart) jobs_.push_back({k, d * restarts + restart, decays[d], int(restart)});
        for (Candidates& c : candidates_) {
            c.pending = perVoxel;
            c.held.resize(perVoxel);
        }
    }

    std::vector<VoxelTrainResult> run() {
        const size_t threads = size_t(std::max(1, tbb::this_task_arena::max_concurrency()));
        // Sixteen lanes only where there are trainings enough to keep them busy: a small bake waits on its longest
        // trainings, whose steps cost more in sixteen lanes than in eight (docs/performance.md). Any kernel gives
        // the same networks.
        const LockstepKernel& kernel = lockstepKernel(jobs_.size() >= size_t(4 * kMaxLockstepLanes) * threads ? kMaxLockstepLanes : 8);
        const size_t lanes = size_t(kernel.lanes);
        const size_t groups = std::clamp<size_t>((jobs_.size() + lanes - 1) / lanes, 1, threads);
        tbb::parallel_for(size_t(0), groups, [&](size_t) { runGroup(kernel); });
        return std::move(out_);
    }

private:
    struct Job {
        size_t voxel;  // index into voxels_
        size_t slot;  // candidate
        float decay;
        int restart;
    };
    // A training in a lane, or waiting for one.
    struct Held {
        std::unique_ptr<Training> training;
        size_t voxel = 0, slot = 0;
    };
    struct Candidates {
        std::mutex mutex;
        size_t pending = 0;
        std::vector<std::unique_ptr<Training>> held;
        bool decided = false;
        double losersSeconds = 0.0;
        size_t awaiting = 0;  // race winners still training
        std::vector<std::pair<size_t, VoxelTrainResult>> winners;  // race winners ended, with their slots
        std::weak_ptr<const VoxelData> data;  // the candidates' shared samples while one of them holds them
    };

    // The next training for a lane: a race's winner to resume, else the next job.
    bool take(Held& h) {
        {
            std::lock_guard<std::mutex> lock(readyMutex_);
            if (!ready_.empty()) {
                h = std::move(ready_.back());
                ready_.pop_back();
                return true;
            }
        }
        const size_t k = next_++;
        if (k >= jobs_.size()) return false;
        const Job& job = jobs_[k];
        h.voxel = job.voxel;
        h.slot = job.slot;
        std::shared_ptr<const VoxelData> data;
        {
            Candidates& c = candidates_[job.voxel];
            std::lock_guard<std::mutex> lock(c.mutex);
            data = c.data.lock();
            if (!data) c.data = data = std::make_shared<const VoxelData>(voxels_[job.voxel], *samples_[job.voxel], settings_);
        }
        h.training = std::make_unique<Training>(voxels_[job.voxel], *samples_[job.voxel], std::move(data), settings_, job.decay, job.restart);
        if (racing_) h.training->raceAt(settings_.raceEpochs);
        return true;
    }

    void finalize(size_t voxel, std::vector<VoxelTrainResult> results, double extraSeconds) {
        out_[voxel] = chooseCandidate(results, *samples_[voxel], settings_);
        out_[voxel].seconds += extraSeconds;
        if (onDone_) onDone_();
    }

    // Results in their candidates' order (as they ended, they are in no fixed order), so that a tie goes the same way.
    static std::vector<VoxelTrainResult> inSlotOrder(std::vector<std::pair<size_t, VoxelTrainResult>> ended) {
        std::sort(ended.begin(), ended.end(), [](const auto& a, const auto& b) { return a.first < b.first; });
        std::vector<VoxelTrainResult> out;
        for (auto& e : ended) out.push_back(std::move(e.second));
        return out;
    }

    // A training that ended or paused at the race: the voxel's result once every candidate has (or every race winner,
    // after the race), or the race's winners back to the lanes.
    void settle(Held h) {
        Candidates& c = candidates_[h.voxel];
        std::unique_lock<std::mutex> lock(c.mutex);
        if (c.decided) {  // a race's winner, ended
            c.winners.emplace_back(h.slot, h.training->takeResult());
            if (--c.awaiting > 0) return;
            const double extra = c.losersSeconds;
            std::vector<VoxelTrainResult> winners = inSlotOrder(std::move(c.winners));
            lock.unlock();
            return finalize(h.voxel, std::move(winners), extra);
        }
        c.held[h.slot] = std::move(h.training);
        if (--c.pending > 0) return;
        std::vector<std::unique_ptr<Training>> held = std::move(c.held);
        if (std::none_of(held.begin(), held.end(), [](const std::unique_ptr<Training>& t) { return t->parked(); })) {
            lock.unlock();
            std::vector<VoxelTrainResult> results;
            for (std::unique_ptr<Training>& t : held) results.push_back(t->takeResult());
            return finalize(h.voxel, std::move(results), 0.0);
        }
        // The race: among each weight decay's starts (or every candidate: raceAll) the lowest held-out error so far wins
        // (the first on a tie); the others stop here. The winners train on to their ends and are compared there.
        std::vector<size_t> winners;
        for (size_t g = 0; g < held.size(); g += raceGroup_) {
            size_t winner = g;
            for (size_t k = g + 1; k < g + raceGroup_; ++k)
                if (held[k]->raceError() < held[winner]->raceError()) winner = k;
            for (size_t k = g; k < g + raceGroup_; ++k)
                if (k != winner) c.losersSeconds += held[k]->seconds();
            winners.push_back(winner);
        }
        c.decided = true;
        std::vector<size_t> running;
        for (size_t w : winners) {
            if (held[w]->done()) c.winners.emplace_back(w, held[w]->takeResult());
            else running.push_back(w);
        }
        c.awaiting = running.size();
        if (running.empty()) {
            std::vector<VoxelTrainResult> ended = inSlotOrder(std::move(c.winners));
            const double extra = c.losersSeconds;
            lock.unlock();
            return finalize(h.voxel, std::move(ended), extra);
        }
        lock.unlock();
        std::lock_guard<std::mutex> readyLock(readyMutex_);
        for (size_t w : running) {
            held[w]->resume();
            ready_.push_back({std::move(held[w]), h.voxel, w});
        }
    }

    // One group of lanes: takes trainings until none is left, stepping all its busy lanes together.
    void runGroup(const LockstepKernel& kernel) {
        LockstepNetworks nets(settings_.shape, kernel.lanes);
        LockstepWorkspace ws;
        Held lane[kMaxLockstepLanes];
        std::vector<float> params;
        for (;;) {
            LockstepLane in[kMaxLockstepLanes];
            int busy = 0;
            for (int j = 0; j < nets.lanes; ++j) busy += fillLane(nets, lane[j], j, in[j], params) ? 1 : 0;
            if (busy == 0) break;
            const Clock::time_point t0 = Clock::now();
            kernel.step(nets, in, settings_.loss, ws);
            const double share = secondsSince(t0) / double(busy);
            for (int j = 0; j < nets.lanes; ++j)
                if (in[j].count > 0 && lane[j].training->stepped(in[j].count, share)) {
                    nets.getLane(j, params);
                    lane[j].training->endEpoch(params);
                }
        }
    }

    // Lane j's next mini-batch into `in`, after settling what ended or paused in it and taking the next training
    // where it is free; false when the lane has nothing left to do.
    bool fillLane(LockstepNetworks& nets, Held& h, int j, LockstepLane& in, std::vector<float>& params) {
        for (;;) {
            if (!h.training && !take(h)) return false;
            Training& t = *h.training;
            if (t.takeFresh()) nets.setLane(j, t.freshParams());
            if (t.takeResumed()) nets.setLaneState(j, t.laneState().params, t.laneState().m, t.laneState().v);
            if (t.parked()) {  // leaves its lane with the lane's state
                Training::LaneState& st = t.laneState();
                nets.getLaneState(j, st.params, st.m, st.v);
            }
            if (t.done() || t.parked()) {
                settle(std::move(h));
                h = Held{};
                continue;
            }
            if (t.wantsStep()) {
                t.fill(in);
                return true;
            }
            nets.getLane(j, params);  // an epoch without samples ends at once
            t.endEpoch(params);
        }
    }

    const std::vector<uint32_t>& voxels_;
    const std::vector<const std::vector<VoxelSample>*>& samples_;
    const TrainSettings& settings_;
    const std::function<void()>& onDone_;
    bool racing_ = false;
    size_t raceGroup_ = 1;  // candidates a race compares: a weight decay's starts, or all of a voxel's (raceAll)
    std::vector<Job> jobs_;
    std::vector<Candidates> candidates_;
    std::vector<VoxelTrainResult> out_;
    std::atomic<size_t> next_{0};
    std::mutex readyMutex_;
    std::vector<Held> ready_;  // race winners to resume
};

}  // namespace

std::vector<VoxelTrainResult> trainVoxels(const std::vector<uint32_t>& voxels, const std::vector<const std::vector<VoxelSample>*>& samples,
                                          const TrainSettings& settings, const std::function<void()>& onDone) {
    if (settings.shape.inputs != kPackedInputs || settings.shape.outputs != 3)
        throw std::invalid_argument("trainVoxels: a voxel network has 9 inputs and 3 outputs");
    return LaneScheduler(voxels, samples, settings, onDone).run();
}

VoxelTrainResult trainVoxel(uint32_t voxel, const std::vector<VoxelSample>& entries, const TrainSettings& settings) {
    return trainVoxels({voxel}, {&entries}, settings).front();
}

}  // namespace nrad
