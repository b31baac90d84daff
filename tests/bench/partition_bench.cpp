// Partition experiment (issue 15: "an octree, or a kd-tree with axis-aligned splits: choose by measurement").
// At equal numbers of networks (bytes), which partition of the scene's box fits the same training samples
// best: the uniform grid, an octree, or a kd-tree, the trees refined greedily where the training radiance
// varies most (the variation a network of one cell has to draw: the sum over its samples of the squared
// deviation of log(1 + demodulated luminance) from the cell's mean, the "expected error reduction"), and
// never where there is no sample (no surface)?
//
// One set of samples (the bake's defaults: 160,000 points x 32 paths, emission out, demodulated), then for
// each partition one network per occupied cell trained exactly as the baker trains a voxel (trainVoxel, 9-9-3,
// weight decay chosen per cell, no blending), and the error over every cell's held-out samples (relMSE, as
// trainVoxel reports it), weighted by held-out counts. Prints one table row per partition.
//
// --criterion error refines by the trained held-out error instead; --scale-samples makes the points grow with
// the networks (points x networks / 27: constant samples per network, as the grid sweep of docs/results.md).
//
// Usage: partition_bench [scene.gltf] [--points N] [--paths N] [--networks 27,64] [--criterion variation|error]
//                        [--scale-samples] [--threads T]
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <string>
#include <vector>

#include <tbb/parallel_for.h>

#include "baker/bake/baker.h"
#include "baker/bake/trainer.h"
#include "baker/bake/training_samples.h"
#include "baker/bake/voxel_grid.h"
#include "baker/lights/light_sampler.h"
#include "baker/render/accel.h"
#include "baker/render/path_tracer.h"
#include "baker/scene/gltf_loader.h"
#include "baker/util/threads.h"

using namespace nrad;

namespace {

struct Cell {
    Bounds3 box;
    std::vector<uint32_t> samples;
    double score = 0.0;  // variation of the learned quantity over the cell's samples
};

float learned(const TrainingSample& t) {
    glm::vec3 y = t.radiance / demodulationDivisor(t);
    return std::log1p(std::max(0.0f, 0.2126f * y.x + 0.7152f * y.y + 0.0722f * y.z));
}

double variation(const std::vector<TrainingSample>& all, const std::vector<uint32_t>& idx) {
    if (idx.size() < 2) return 0.0;
    double sum = 0.0, sum2 = 0.0;
    for (uint32_t i : idx) {
        double v = learned(all[i]);
        sum += v;
        sum2 += v * v;
    }
    double n = double(idx.size());
    return std::max(0.0, sum2 - sum * sum / n);
}

Cell makeCell(const std::vector<TrainingSample>& all, const Bounds3& box, const std::vector<uint32_t>& from) {
    Cell c;
    c.box = box;
    for (uint32_t i : from) {
        const glm::vec3& p = all[i].position;
        // Half-open on the upper side, as the voxel rule (the root box is padded, so nothing is lost).
        if (p.x >= box.lower.x && p.y >= box.lower.y && p.z >= box.lower.z && p.x < box.upper.x && p.y < box.upper.y &&
            p.z < box.upper.z)
            c.samples.push_back(i);
    }
    c.score = variation(all, c.samples);
    return c;
}

std::vector<Cell> split(const std::vector<TrainingSample>& all, const Cell& c, bool octree) {
    std::vector<Cell> out;
    glm::vec3 mid = c.box.center();
    if (octree) {
        for (int k = 0; k < 8; ++k) {
            Bounds3 b;
            for (int a = 0; a < 3; ++a) {
                b.lower[a] = (k >> a & 1) ? mid[a] : c.box.lower[a];
                b.upper[a] = (k >> a & 1) ? c.box.upper[a] : mid[a];
            }
            out.push_back(makeCell(all, b, c.samples));
        }
        return out;
    }
    // kd-tree: of the midpoint splits of the three axes, the one that removes the most variation.
    double best = -1.0;
    for (int a = 0; a < 3; ++a) {
        Bounds3 lo = c.box, hi = c.box;
        lo.upper[a] = hi.lower[a] = mid[a];
        Cell l = makeCell(all, lo, c.samples), h = makeCell(all, hi, c.samples);
        double gain = c.score - l.score - h.score;
        if (gain > best) {
            best = gain;
            out = {l, h};
        }
    }
    return out;
}

size_t occupied(const std::vector<Cell>& cells) {
    size_t n = 0;
    for (const Cell& c : cells) n += c.samples.empty() ? 0 : 1;
    return n;
}

// A cell's network, trained as the baker trains a voxel (no blending), and its held-out error mass.
VoxelTrainResult trainCell(const std::vector<TrainingSample>& all, const Cell& c, uint32_t id) {
    std::vector<VoxelSample> vs;
    glm::vec3 ctr = c.box.center(), half = 0.5f * c.box.extent();
    for (uint32_t s : c.samples)
        vs.push_back({&all[s], 1.0f, glm::clamp((all[s].position - ctr) / half, glm::vec3(-1.0f), glm::vec3(1.0f))});
    static const TrainSettings settings;  // the baker's defaults (one object: GCC 12 misreports temporaries)
    return trainVoxel(id, vs, settings);
}

// Greedy refinement until `networks` occupied cells (an octree split may overshoot by up to 7): split the
// cell of the largest score, the variation of its samples' radiance (criterion "variation") or the held-out
// error of its trained network times its samples (criterion "error": every new cell is trained at once).
std::vector<Cell> refine(const std::vector<TrainingSample>& all, const Bounds3& root, size_t networks, bool octree,
                         bool byError) {
    std::vector<uint32_t> every(all.size());
    for (uint32_t i = 0; i < every.size(); ++i) every[i] = i;
    std::vector<Cell> cells = {makeCell(all, root, every)};
    auto scoreByError = [&](std::vector<Cell>& cs, size_t from) {
        tbb::parallel_for(from, cs.size(), [&](size_t i) {
            VoxelTrainResult r = trainCell(all, cs[i], uint32_t(i));
            cs[i].score = r.heldOutRelMse * double(cs[i].samples.size());
        });
    };
    if (byError) scoreByError(cells, 0);
    while (occupied(cells) < networks) {
        size_t worst = 0;
        for (size_t i = 1; i < cells.size(); ++i)
            if (cells[i].score > cells[worst].score) worst = i;
        if (cells[worst].samples.size() < 64) break;  // nothing left worth a network
        std::vector<Cell> children = split(all, cells[worst], octree);
        cells.erase(cells.begin() + std::ptrdiff_t(worst));
        const size_t first = cells.size();
        for (Cell& ch : children)
            if (!ch.samples.empty()) cells.push_back(std::move(ch));
        if (byError) scoreByError(cells, first);
    }
    return cells;
}

std::vector<Cell> uniform(const std::vector<TrainingSample>& all, const Bounds3& root, int g) {
    std::vector<uint32_t> every(all.size());
    for (uint32_t i = 0; i < every.size(); ++i) every[i] = i;
    std::vector<Cell> cells;
    glm::vec3 size = root.extent() / float(g);
    for (int z = 0; z < g; ++z)
        for (int y = 0; y < g; ++y)
            for (int x = 0; x < g; ++x) {
                Bounds3 b;
                b.lower = root.lower + size * glm::vec3(x, y, z);
                b.upper = root.lower + size * glm::vec3(x + 1, y + 1, z + 1);
                b.upper = glm::vec3(x == g - 1 ? root.upper.x : b.upper.x, y == g - 1 ? root.upper.y : b.upper.y,
                                    z == g - 1 ? root.upper.z : b.upper.z);
                Cell c = makeCell(all, b, every);
                if (!c.samples.empty()) cells.push_back(std::move(c));
            }
    return cells;
}

struct Score {
    size_t networks = 0;
    double relMse = 0.0;  // over every held-out sample
    double seconds = 0.0;
    double finestLevels = 0.0;  // log8 of (root volume / smallest cell's volume): octree levels below the root
};

Score evaluate(const std::vector<TrainingSample>& all, const std::vector<Cell>& cells, const Bounds3& root) {
    auto t0 = std::chrono::steady_clock::now();
    std::vector<VoxelTrainResult> results(cells.size());
    tbb::parallel_for(size_t(0), cells.size(), [&](size_t i) { results[i] = trainCell(all, cells[i], uint32_t(i)); });
    Score s;
    s.networks = cells.size();
    double err = 0.0, n = 0.0;
    for (const VoxelTrainResult& r : results) {
        err += r.heldOutRelMse * double(r.heldOutCount);
        n += double(r.heldOutCount);
    }
    s.relMse = n > 0.0 ? err / n : 0.0;
    s.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    auto volume = [](const Bounds3& b) { return double(b.extent().x) * double(b.extent().y) * double(b.extent().z); };
    for (const Cell& c : cells) s.finestLevels = std::max(s.finestLevels, std::log(volume(root) / volume(c.box)) / std::log(8.0));
    return s;
}

}  // namespace

int main(int argc, char** argv) {
    std::string scenePath = std::string(NRAD_SOURCE_DIR) + "/scenes/cornell-box/cornell-box.gltf";
    SampleSettings ss = defaultBakeSamples();
    std::vector<size_t> budgets = {27, 64};
    int threads = 0;
    bool byError = false, scaleSamples = false;
    for (int i = 1; i < argc; ++i) {
        std::string a = argv[i];
        auto next = [&]() { return i + 1 < argc ? argv[++i] : (std::fprintf(stderr, "%s needs a value\n", a.c_str()), std::exit(2), ""); };
        if (a == "--points") ss.points = uint32_t(std::atol(next()));
        else if (a == "--paths") ss.paths = uint32_t(std::atol(next()));
        else if (a == "--threads") threads = std::atoi(next());
        else if (a == "--criterion") byError = std::string(next()) == "error";
        else if (a == "--scale-samples") scaleSamples = true;
        else if (a == "--networks") {
            budgets.clear();
            std::string list = next();
            for (size_t at = 0; at <= list.size();) {
                size_t comma = list.find(',', at);
                budgets.push_back(size_t(std::atol(list.substr(at, comma - at).c_str())));
                if (comma == std::string::npos) break;
                at = comma + 1;
            }
        } else if (a[0] != '-') scenePath = a;
        else {
            std::fprintf(stderr, "usage: partition_bench [scene.gltf] [--points N] [--paths N] [--networks 27,64] "
                                 "[--criterion variation|error] [--scale-samples] [--threads T]\n");
            return 2;
        }
    }
    ThreadScope scope(threads);
    Scene scene = loadGltf(scenePath);
    if (!scene.hasLight()) scene.environment = defaultSky();
    Accel accel(scene);
    LightSampler lights(scene);
    PathTracer tracer(scene, accel, lights);
    tracer.setRouletteThreshold(kTrainingRouletteThreshold);  // as the baker traces its targets
    VoxelGrid grid(scene.bounds, glm::uvec3(8));  // only for the per-cell floor of samples
    SurfacePieces pieces(scene.mesh, grid);
    const format::Grid& g = grid.grid();
    Bounds3 root;  // the baker's padded grid box (the uniform grids are the baker's own voxels)
    root.lower = glm::vec3(g.lower[0], g.lower[1], g.lower[2]);
    root.upper = glm::vec3(g.upper[0], g.upper[1], g.upper[2]);
    auto samplesFor = [&](size_t networks) {
        SampleSettings s = ss;
        if (scaleSamples) s.points = uint32_t(double(ss.points) * double(networks) / 27.0);
        SampleStats st;
        return generateTrainingSamples(scene, tracer, grid, pieces, s, st);
    };
    std::printf("%s: %u points x %u paths%s, refinement by %s\n", scenePath.c_str(), ss.points, ss.paths,
                scaleSamples ? " per 27 networks" : "", byError ? "held-out error" : "radiance variation");
    std::printf("| partition | networks | samples | held-out relMSE | finest cell (octree levels) | training s |\n|---|---|---|---|---|---|\n");
    for (int gdim : {3, 4}) {
        std::vector<TrainingSample> samples = samplesFor(size_t(gdim * gdim * gdim));
        std::vector<Cell> cells = uniform(samples, root, gdim);
        Score s = evaluate(samples, cells, root);
        std::printf("| uniform %dx%dx%d | %zu | %zu | %.5f | %.2f | %.1f |\n", gdim, gdim, gdim, s.networks, samples.size(), s.relMse,
                    s.finestLevels, s.seconds);
        std::fflush(stdout);
    }
    for (size_t n : budgets) {
        std::vector<TrainingSample> samples = samplesFor(n);
        for (bool octree : {true, false}) {
            std::vector<Cell> cells = refine(samples, root, n, octree, byError);
            Score s = evaluate(samples, cells, root);
            std::printf("| %s, %zu networks asked | %zu | %zu | %.5f | %.2f | %.1f |\n", octree ? "octree" : "kd-tree", n,
                        s.networks, samples.size(), s.relMse, s.finestLevels, s.seconds);
            std::fflush(stdout);
        }
    }
    return 0;
}
