// libnrad: loading safety (every prefix, flipped bytes, bad magic, versions, trailing bytes, huge counts),
// evaluation against an independent plain forward pass, every SIMD kernel against the scalar one, point
// flags, both batch layouts, concurrent evaluation (agreement with the baker's own forward pass: runtime_baker_test.cpp).
#include <nrad/eval.h>
#include <nrad/format.h>
#include <nrad/nrad.h>
#include <nrad/nrad.hpp>

#include <cmath>
#include <fstream>
#include <limits>
#include <random>
#include <thread>

#include <gtest/gtest.h>

#include "runtime/src/testing.h"  // rt::testing::blendedBlocksSoFar(): which path the vector kernels took
#include "support/test_paths.h"
#include "support/random_asset.h"
#include "support/test_trees.h"

namespace nrad {
namespace {

using test::randomAsset;

size_t networkOf(const format::Asset& a, int64_t voxel) {
    for (size_t i = 0; i < a.voxels.size(); ++i)
        if (a.voxels[i].index == uint32_t(voxel)) return i;
    return a.voxels.size();
}

// The networks that shade p (nrad/eval.h), with the flag the runtime must give.
int supportsOf(const format::Asset& a, const float p[3], eval::Support s[eval::kMaxSupports], uint32_t& flag) {
    int count = eval::Partition(a).supports(p, s);
    if (count == 0) {
        flag = NRAD_POINT_OUTSIDE_GRID;
        return 0;
    }
    count = eval::keepOccupied(s, count, [&](int64_t v) { return networkOf(a, v) < a.voxels.size(); });
    flag = count > 0 ? NRAD_POINT_OK : NRAD_POINT_EMPTY_VOXEL;
    return count;
}

glm::vec3 referenceOne(const format::Asset& a, size_t net, const float local[3], const glm::vec3& n, const glm::vec3& d);

// Independent forward pass: straight from the format's definition, in double, blended as eval.h says.
glm::vec3 reference(const format::Asset& a, const glm::vec3& p, const glm::vec3& n, const glm::vec3& d, uint32_t& flag) {
    float q[3] = {p.x, p.y, p.z};
    eval::Support s[eval::kMaxSupports];
    const int count = supportsOf(a, q, s, flag);
    glm::dvec3 sum(0.0);
    for (int i = 0; i < count; ++i) sum += double(s[i].weight) * glm::dvec3(referenceOne(a, networkOf(a, s[i].voxel), s[i].local, n, d));
    return glm::vec3(sum);
}

glm::vec3 referenceOne(const format::Asset& a, size_t net, const float local[3], const glm::vec3& n, const glm::vec3& d) {
    std::vector<double> x = {local[0], local[1], local[2], n.x, n.y, n.z, d.x, d.y, d.z};
    const float* w = a.weights.data() + net * a.topology.parameterCount();
    std::vector<uint32_t> widths = a.topology.hiddenWidths;
    widths.push_back(3);
    for (size_t l = 0; l < widths.size(); ++l) {
        std::vector<double> y(widths[l]);
        const float* b = w + widths[l] * x.size();
        for (size_t o = 0; o < y.size(); ++o) {
            double s = b[o];
            for (size_t i = 0; i < x.size(); ++i) s += double(w[o * x.size() + i]) * x[i];
            y[o] = l + 1 == widths.size() ? s : std::max(0.0, s);
        }
        w = b + y.size();
        x = y;
    }
    glm::vec3 L;
    for (int k = 0; k < 3; ++k) {
        double v = a.topology.outputTransform == format::OutputTransform::Exponential ? std::expm1(x[size_t(k)]) : x[size_t(k)];
        L[k] = float(a.voxels[net].scale * std::max(0.0, v));
    }
    return L;
}

std::vector<NradKernel> kernels() {
    std::vector<NradKernel> k = {NRAD_KERNEL_SCALAR};
    for (NradKernel c : {NRAD_KERNEL_AVX2, NRAD_KERNEL_AVX512, NRAD_KERNEL_NEON})
        if (nradKernelSupported(c)) k.push_back(c);
    return k;
}

struct Points {
    std::vector<float> p, n, d;
};

Points randomPoints(size_t count, uint32_t seed) {
    std::mt19937 rng(seed);
    std::uniform_real_distribution<float> u(-1.0f, 1.0f);
    Points pts;
    for (size_t i = 0; i < count; ++i) {
        // Mostly inside the grid of randomAsset, some outside.
        glm::vec3 p(u(rng) * 2.0f + 0.5f, u(rng) * 2.5f + 0.5f, u(rng) * 3.5f + 0.5f);
        glm::vec3 n = glm::normalize(glm::vec3(u(rng), u(rng), u(rng)) + glm::vec3(0, 0, 1e-3f));
        glm::vec3 d = glm::normalize(glm::vec3(u(rng), u(rng), u(rng)) + glm::vec3(1e-3f, 0, 0));
        for (int k = 0; k < 3; ++k) {
            pts.p.push_back(p[k]);
            pts.n.push_back(n[k]);
            pts.d.push_back(d[k]);
        }
    }
    return pts;
}

TEST(Runtime, EveryKernelMatchesAPlainForwardPass) {
    for (auto hidden : {std::vector<uint32_t>{9}, std::vector<uint32_t>{16, 8}, std::vector<uint32_t>{3}}) {
        for (auto transform : {format::OutputTransform::ClampedLinear, format::OutputTransform::Exponential}) {
            format::Asset a = randomAsset(hidden, format::WeightEncoding::Float32, transform, 5);
            std::vector<uint8_t> bytes = format::encode(a);
            nrad::Asset asset;
            ASSERT_EQ(asset.loadFromMemory(bytes.data(), bytes.size()), NRAD_OK);
            Points pts = randomPoints(1000, 9);
            for (NradKernel k : kernels()) {
                ASSERT_EQ(nradSelectKernel(k), NRAD_OK);
                ASSERT_EQ(nradActiveKernel(), k);
                std::vector<float> rgb(pts.p.size());
                std::vector<uint8_t> flags(1000);
                ASSERT_EQ(asset.evaluateBatch(1000, pts.p.data(), pts.n.data(), pts.d.data(), rgb.data(), flags.data()), NRAD_OK);
                int located = 0;
                for (size_t i = 0; i < 1000; ++i) {
                    uint32_t flag;
                    glm::vec3 ref = reference(a, {pts.p[3 * i], pts.p[3 * i + 1], pts.p[3 * i + 2]},
                                              {pts.n[3 * i], pts.n[3 * i + 1], pts.n[3 * i + 2]},
                                              {pts.d[3 * i], pts.d[3 * i + 1], pts.d[3 * i + 2]}, flag);
                    ASSERT_EQ(flags[i], flag) << i;
                    located += flag == NRAD_POINT_OK;
                    for (int c = 0; c < 3; ++c)
                        ASSERT_NEAR(rgb[3 * i + size_t(c)], ref[c], 2e-5f * std::max(1.0f, std::abs(ref[c])))
                            << "kernel " << k << " point " << i;
                }
                EXPECT_GT(located, 300);
                EXPECT_LT(located, 700);
            }
        }
    }
    nradSelectKernel(NRAD_KERNEL_AUTO);
}

// The kd-tree partition: the uniform tree shades exactly as the grid (bit for bit, every kernel, blended or
// not), and a random tree of leaves of many sizes matches the plain forward pass through eval.h's supports.
// Both ways the vector path locates in a kd-tree (the rectilinear table of small trees, and the start table's
// descent that larger ones take), each asset loaded after testing::setMaxRectCells.
const size_t kRectLimits[2] = {rt::LocateTree::kMaxRectCells, 0};

TEST(Runtime, TreeAssetsMatchTheGridAndAPlainForwardPass) {
    for (size_t rect : kRectLimits)
    for (float band : {0.0f, 0.125f}) {
        SCOPED_TRACE("rectilinear table up to " + std::to_string(rect) + " cells");
        rt::testing::setMaxRectCells(rect);
        format::Asset grid = randomAsset({9}, format::WeightEncoding::Float16, format::OutputTransform::Exponential, 21,
                                         glm::uvec3(4, 3, 5), band);
        format::Asset tree = grid;
        tree.header.flags |= format::kFlagTree;
        tree.tree = format::uniformTree(grid.grid.dims);
        const std::vector<uint8_t> gb = format::encode(grid), tb = format::encode(tree);
        nrad::Asset ga, ta;
        ASSERT_EQ(ga.loadFromMemory(gb.data(), gb.size()), NRAD_OK);
        ASSERT_EQ(ta.loadFromMemory(tb.data(), tb.size()), NRAD_OK);
        Points pts = randomPoints(3000, 4);
        for (NradKernel k : kernels()) {
            ASSERT_EQ(nradSelectKernel(k), NRAD_OK);
            std::vector<float> a(pts.p.size()), b(pts.p.size());
            std::vector<uint8_t> fa(3000), fb(3000);
            ASSERT_EQ(ga.evaluateBatch(3000, pts.p.data(), pts.n.data(), pts.d.data(), a.data(), fa.data()), NRAD_OK);
            ASSERT_EQ(ta.evaluateBatch(3000, pts.p.data(), pts.n.data(), pts.d.data(), b.data(), fb.data()), NRAD_OK);
            EXPECT_EQ(fa, fb);
            EXPECT_EQ(std::memcmp(a.data(), b.data(), a.size() * sizeof(float)), 0) << "kernel " << k << " band " << band;
        }
        // A random tree over a finer lattice of the same box; again with every third node hard where inner (no band
        // across its plane: format 2.3).
        for (uint32_t hardEvery : {0u, 3u}) {
        SCOPED_TRACE("hard every " + std::to_string(hardEvery));
        format::Asset adaptive = grid;
        ASSERT_FALSE(test::makeRandomTreeAsset(adaptive, 16, 90, 8, 3, 1, hardEvery).empty());
        const std::vector<uint8_t> ab = format::encode(adaptive);
        nrad::Asset aa;
        ASSERT_EQ(aa.loadFromMemory(ab.data(), ab.size()), NRAD_OK);
        ASSERT_EQ(format::decode(ab.data(), ab.size(), adaptive), format::DecodeStatus::Ok);
        for (NradKernel k : kernels()) {
            ASSERT_EQ(nradSelectKernel(k), NRAD_OK);
            std::vector<float> rgb(pts.p.size());
            std::vector<uint8_t> flags(3000);
            ASSERT_EQ(aa.evaluateBatch(3000, pts.p.data(), pts.n.data(), pts.d.data(), rgb.data(), flags.data()), NRAD_OK);
            for (size_t i = 0; i < 3000; ++i) {
                uint32_t flag;
                const glm::vec3 ref = reference(adaptive, {pts.p[3 * i], pts.p[3 * i + 1], pts.p[3 * i + 2]},
                                                {pts.n[3 * i], pts.n[3 * i + 1], pts.n[3 * i + 2]},
                                                {pts.d[3 * i], pts.d[3 * i + 1], pts.d[3 * i + 2]}, flag);
                ASSERT_EQ(flags[i], flag) << i;
                for (int c = 0; c < 3; ++c)
                    ASSERT_NEAR(rgb[3 * i + size_t(c)], ref[c], 2e-5f * std::max(1.0f, std::abs(ref[c]))) << "kernel " << k << " point " << i;
            }
        }
        }  // hardEvery
    }
    nradSelectKernel(NRAD_KERNEL_AUTO);
    rt::testing::setMaxRectCells(rt::LocateTree::kMaxRectCells);
}

// Runs of points in one voxel, as a renderer's coherent batches have: most vectors of 8 or 16 points lie
// in one voxel and take the SIMD kernels' vector locate-and-evaluate path; run lengths that are not
// multiples of the vector width make vectors span two voxels; bad points (outside, in an empty voxel,
// non-finite) sprinkled among them send their vector to the one-point-at-a-time path; voxel faces and
// the grid's upper face exercise the voxel rule's borders.
Points coherentPoints(const format::Asset& a, uint32_t seed) {
    std::mt19937 rng(seed);
    std::uniform_real_distribution<float> u(0.0f, 1.0f), s(-1.0f, 1.0f);
    const format::Grid& g = a.grid;
    Points pts;
    auto push = [&](const glm::vec3& p, const glm::vec3& n, const glm::vec3& d) {
        for (int k = 0; k < 3; ++k) {
            pts.p.push_back(p[k]);
            pts.n.push_back(n[k]);
            pts.d.push_back(d[k]);
        }
    };
    for (int round = 0; round < 3; ++round)
        for (uint32_t v = 0; v < g.voxelCount(); ++v) {
            uint32_t c[3] = {v % g.dims[0], (v / g.dims[0]) % g.dims[1], v / (g.dims[0] * g.dims[1])};
            int run = int(rng() % 70);
            for (int i = 0; i < run; ++i) {
                glm::vec3 p;
                for (int k = 0; k < 3; ++k) {
                    float size = (g.upper[k] - g.lower[k]) / float(g.dims[k]);
                    float f = i % 29 == 3 ? 0.0f : i % 31 == 5 ? 1.0f : u(rng);  // faces now and then
                    p[k] = std::min(g.upper[k], g.lower[k] + size * (float(c[k]) + f));
                }
                glm::vec3 n = glm::normalize(glm::vec3(s(rng), s(rng), s(rng)) + glm::vec3(0, 0, 1e-3f));
                glm::vec3 d = glm::normalize(glm::vec3(s(rng), s(rng), s(rng)) + glm::vec3(1e-3f, 0, 0));
                uint32_t r = rng() % 97;
                if (r == 0) p.x = g.upper[0] + 0.5f;  // outside
                if (r == 1) n.y = std::nanf("");
                if (r == 2) d.z = std::numeric_limits<float>::infinity();
                push(p, n, d);
            }
        }
    return pts;
}

// Coherent vectors of kd-tree assets are located in registers (the first point's leaf, every point inside it
// clear of the bands) and must give the bits of the general path: runs of points in each leaf of a random tree
// (planes hit exactly now and then, bad points among them) through every vector kernel, in one batch against
// one point per call (the general path); and the uniform tree against the grid on coherent runs.
TEST(Runtime, CoherentTreeVectorsAreLocatedInRegistersBitForBit) {
    const uint64_t before = rt::testing::treeBlocksSoFar();
    for (size_t rect : kRectLimits)
    for (float band : {0.0f, 0.125f}) {
        SCOPED_TRACE("band " + std::to_string(band) + ", rectilinear table up to " + std::to_string(rect) + " cells");
        rt::testing::setMaxRectCells(rect);
        format::Asset grid = randomAsset({9}, format::WeightEncoding::Float16, format::OutputTransform::Exponential, 23,
                                         glm::uvec3(4, 3, 5), band);
        format::Asset uniform = grid;
        uniform.header.flags |= format::kFlagTree;
        uniform.tree = format::uniformTree(grid.grid.dims);
        format::Asset adaptive = grid;
        const std::vector<format::TreeBox> boxes = test::makeRandomTreeAsset(adaptive, 16, 60, 5, 5, 2);
        ASSERT_FALSE(boxes.empty());
        const uint32_t leaves = uint32_t(boxes.size());
        std::mt19937 rng(8);
        // Runs of points in each leaf, in leaf order.
        std::uniform_real_distribution<float> u(0.0f, 1.0f), s(-1.0f, 1.0f);
        Points pts;
        const format::Grid& g = adaptive.grid;
        for (int round = 0; round < 2; ++round)
            for (uint32_t leaf = 0; leaf < leaves; ++leaf) {
                const int run = int(rng() % 90);
                for (int i = 0; i < run; ++i) {
                    for (int k = 0; k < 3; ++k) {
                        const float size = (g.upper[k] - g.lower[k]) / float(g.dims[k]);
                        const float f = i % 23 == 4 ? 0.0f : u(rng);  // the leaf's lower plane now and then
                        const float lattice = float(boxes[leaf].lo[k]) + f * float(boxes[leaf].hi[k] - boxes[leaf].lo[k]);
                        pts.p.push_back(std::min(g.upper[k], g.lower[k] + size * lattice));
                        pts.n.push_back(s(rng));
                        pts.d.push_back(s(rng));
                    }
                    const size_t at = pts.p.size() - 3;
                    if (rng() % 89 == 0) pts.n[at] = std::nanf("");
                    if (rng() % 89 == 0) pts.p[at] = g.upper[0] + 0.25f;
                }
            }
        const std::vector<uint8_t> gb = format::encode(grid), ub = format::encode(uniform), ab = format::encode(adaptive);
        nrad::Asset ga, ua, aa;
        ASSERT_EQ(ga.loadFromMemory(gb.data(), gb.size()), NRAD_OK);
        ASSERT_EQ(ua.loadFromMemory(ub.data(), ub.size()), NRAD_OK);
        ASSERT_EQ(aa.loadFromMemory(ab.data(), ab.size()), NRAD_OK);
        const size_t n = pts.p.size() / 3;
        ASSERT_GT(n, 2000u);
        Points grided = coherentPoints(grid, 6);
        const size_t m = grided.p.size() / 3;
        for (NradKernel k : kernels()) {
            ASSERT_EQ(nradSelectKernel(k), NRAD_OK);
            std::vector<float> batch(3 * n), single(3 * n);
            std::vector<uint8_t> flags(n);
            ASSERT_EQ(aa.evaluateBatch(n, pts.p.data(), pts.n.data(), pts.d.data(), batch.data(), flags.data()), NRAD_OK);
            for (size_t i = 0; i < n; ++i) {
                uint32_t flag = 0;
                ASSERT_EQ(nradEvaluate(aa.get(), &pts.p[3 * i], &pts.n[3 * i], &pts.d[3 * i], &single[3 * i], &flag), NRAD_OK);
                ASSERT_EQ(uint32_t(flags[i]), flag) << "kernel " << k << " point " << i;
                ASSERT_EQ(std::memcmp(&batch[3 * i], &single[3 * i], 12), 0) << "kernel " << k << " point " << i;
            }
            std::vector<float> a(3 * m), b(3 * m);
            std::vector<uint8_t> fa(m), fb(m);
            ASSERT_EQ(ga.evaluateBatch(m, grided.p.data(), grided.n.data(), grided.d.data(), a.data(), fa.data()), NRAD_OK);
            ASSERT_EQ(ua.evaluateBatch(m, grided.p.data(), grided.n.data(), grided.d.data(), b.data(), fb.data()), NRAD_OK);
            EXPECT_EQ(fa, fb);
            EXPECT_EQ(std::memcmp(a.data(), b.data(), a.size() * sizeof(float)), 0) << "kernel " << k;
        }
    }
    nradSelectKernel(NRAD_KERNEL_AUTO);
    rt::testing::setMaxRectCells(rt::LocateTree::kMaxRectCells);
    if (kernels().size() > 1) {
        EXPECT_GT(rt::testing::treeBlocksSoFar(), before) << "no vector was located in registers";
    }
}

// The contract's own vectors (nrad/eval.h: locate -> network, encodeInputs, forward, decodeOutputs) against
// every kernel, random and coherent batches: the scalar kernel is eval.h itself (bit for bit); the SIMD
// kernels fuse multiply-adds and order their sums their own way (1e-5 of max(1, value)).
TEST(Runtime, EveryKernelMatchesTheContractsVectors) {
    for (float band : {0.0f, 0.2f, 0.5f})
    for (auto transform : {format::OutputTransform::ClampedLinear, format::OutputTransform::Exponential}) {
        SCOPED_TRACE("band " + std::to_string(band));
        format::Asset a = randomAsset({9}, format::WeightEncoding::Float16, transform, 33, glm::uvec3(3, 3, 3), band);
        std::vector<uint8_t> bytes = format::encode(a);
        nrad::Asset asset;
        ASSERT_EQ(asset.loadFromMemory(bytes.data(), bytes.size()), NRAD_OK);
        Points pts = coherentPoints(a, 8);
        Points more = randomPoints(2000, 12);
        pts.p.insert(pts.p.end(), more.p.begin(), more.p.end());
        pts.n.insert(pts.n.end(), more.n.begin(), more.n.end());
        pts.d.insert(pts.d.end(), more.d.begin(), more.d.end());
        const size_t n = pts.p.size() / 3;
        // The vectors.
        std::vector<float> expected(3 * n, 0.0f);
        std::vector<uint8_t> expectedFlag(n, NRAD_POINT_OK);
        float scratch[eval::kForwardScratch];
        for (size_t i = 0; i < n; ++i) {
            const float *p = &pts.p[3 * i], *nn = &pts.n[3 * i], *d = &pts.d[3 * i];
            bool finite = true;
            for (int k = 0; k < 3; ++k) finite = finite && std::isfinite(p[k]) && std::isfinite(nn[k]) && std::isfinite(d[k]);
            if (!finite) {
                expectedFlag[i] = NRAD_POINT_INVALID_INPUT;
                continue;
            }
            eval::Support sup[eval::kMaxSupports];
            uint32_t flag = 0;
            const int count = supportsOf(a, p, sup, flag);
            expectedFlag[i] = uint8_t(flag);
            for (int j = 0; j < count; ++j) {  // weight x radiance, summed in the supports' order
                const size_t net = networkOf(a, sup[j].voxel);
                float x[eval::kInputs], y[eval::kOutputs], rgb[eval::kOutputs];
                eval::encodeInputs(sup[j].local, nn, d, x);
                eval::forward(a.topology, a.weights.data() + net * a.topology.parameterCount(), x, y, scratch);
                eval::decodeOutputs(transform, a.voxels[net].scale, y, rgb);
                for (int c = 0; c < 3; ++c) expected[3 * i + size_t(c)] += sup[j].weight * rgb[c];
            }
        }
        for (NradKernel k : kernels()) {
            ASSERT_EQ(nradSelectKernel(k), NRAD_OK);
            std::vector<float> rgb(3 * n, -1.0f);
            std::vector<uint8_t> flags(n, 255);
            ASSERT_EQ(asset.evaluateBatch(n, pts.p.data(), pts.n.data(), pts.d.data(), rgb.data(), flags.data()), NRAD_OK);
            for (size_t i = 0; i < n; ++i) {
                ASSERT_EQ(flags[i], expectedFlag[i]) << "kernel " << k << " point " << i;
                for (int c = 0; c < 3; ++c) {
                    float e = expected[3 * i + size_t(c)], r = rgb[3 * i + size_t(c)];
                    if (k == NRAD_KERNEL_SCALAR)
                        ASSERT_EQ(r, e) << "point " << i;
                    else
                        ASSERT_NEAR(r, e, 1e-5f * std::max(1.0f, e)) << "kernel " << k << " point " << i;
                }
            }
        }
    }
    nradSelectKernel(NRAD_KERNEL_AUTO);
}

TEST(Runtime, CoherentRunsInBothLayoutsMatchAPlainForwardPass) {
    for (float band : {0.0f, 0.125f})
    for (auto hidden : {std::vector<uint32_t>{9}, std::vector<uint32_t>{16, 8}}) {
        SCOPED_TRACE("band " + std::to_string(band));
        format::Asset a = randomAsset(hidden, format::WeightEncoding::Float16, format::OutputTransform::Exponential, 21,
                                      glm::uvec3(3, 3, 3), band);
        std::vector<uint8_t> bytes = format::encode(a);
        nrad::Asset asset;
        ASSERT_EQ(asset.loadFromMemory(bytes.data(), bytes.size()), NRAD_OK);
        Points pts = coherentPoints(a, 4);
        const size_t n = pts.p.size() / 3;
        ASSERT_GT(n, 1500u);
        std::vector<glm::vec3> ref(n);
        std::vector<uint32_t> refFlag(n);
        size_t counts[8] = {};
        for (size_t i = 0; i < n; ++i) {
            ref[i] = reference(a, {pts.p[3 * i], pts.p[3 * i + 1], pts.p[3 * i + 2]}, {pts.n[3 * i], pts.n[3 * i + 1], pts.n[3 * i + 2]},
                               {pts.d[3 * i], pts.d[3 * i + 1], pts.d[3 * i + 2]}, refFlag[i]);
            bool finite = true;
            for (int k = 0; k < 3; ++k) finite &= std::isfinite(pts.n[3 * i + size_t(k)]) && std::isfinite(pts.d[3 * i + size_t(k)]);
            if (!finite) refFlag[i] = NRAD_POINT_INVALID_INPUT, ref[i] = glm::vec3(0.0f);
            ++counts[refFlag[i]];
        }
        EXPECT_GT(counts[NRAD_POINT_OK], n / 3);
        EXPECT_GT(counts[NRAD_POINT_EMPTY_VOXEL], band > 0.0f ? n / 6 : n / 3);  // a band reaches into empty voxels
        EXPECT_GT(counts[NRAD_POINT_OUTSIDE_GRID], 5u);
        EXPECT_GT(counts[NRAD_POINT_INVALID_INPUT], 10u);
        std::vector<float> soa[12];
        for (int k = 0; k < 9; ++k)
            for (size_t i = 0; i < n; ++i) soa[k].push_back((k < 3 ? pts.p : k < 6 ? pts.n : pts.d)[3 * i + size_t(k % 3)]);
        for (NradKernel k : kernels()) {
            ASSERT_EQ(nradSelectKernel(k), NRAD_OK);
            // Every prefix length modulo the vector widths, from several starting offsets.
            for (size_t offset : {size_t(0), size_t(1), size_t(7), size_t(13)}) {
                const size_t m = n - offset;
                std::vector<float> rgb(3 * m, -1.0f);
                std::vector<uint8_t> flags(m, 99);
                ASSERT_EQ(asset.evaluateBatch(m, &pts.p[3 * offset], &pts.n[3 * offset], &pts.d[3 * offset], rgb.data(), flags.data()),
                          NRAD_OK);
                for (int c = 9; c < 12; ++c) soa[c].assign(m, -1.0f);
                std::vector<uint8_t> soaFlags(m, 99);
                NradBatchSoA b{soa[0].data() + offset, soa[1].data() + offset, soa[2].data() + offset, soa[3].data() + offset,
                               soa[4].data() + offset, soa[5].data() + offset, soa[6].data() + offset, soa[7].data() + offset,
                               soa[8].data() + offset, soa[9].data(), soa[10].data(), soa[11].data(), soaFlags.data()};
                ASSERT_EQ(asset.evaluateBatch(m, b), NRAD_OK);
                for (size_t j = 0; j < m; ++j) {
                    size_t i = j + offset;
                    ASSERT_EQ(flags[j], refFlag[i]) << "kernel " << k << " point " << i;
                    ASSERT_EQ(soaFlags[j], refFlag[i]) << "kernel " << k << " point " << i;
                    for (int c = 0; c < 3; ++c) {
                        ASSERT_NEAR(rgb[3 * j + size_t(c)], ref[i][c], 2e-5f * std::max(1.0f, std::abs(ref[i][c])))
                            << "kernel " << k << " point " << i;
                        ASSERT_EQ(soa[9 + c][j], rgb[3 * j + size_t(c)]) << "kernel " << k << " point " << i;
                    }
                }
            }
        }
    }
    nradSelectKernel(NRAD_KERNEL_AUTO);
}

// Bit for bit: a point gets the same result in any batch, layout or path (vector block, blended block,
// grouped pass, single point).
TEST(Runtime, SoAAndInterleavedAndSinglePointAgree) {
    // Both output transforms: two blocks evaluated one after the other take theirs together (toRadianceTwo).
    for (format::OutputTransform transform : {format::OutputTransform::Exponential, format::OutputTransform::ClampedLinear})
    for (float band : {0.0f, 0.25f}) {
    SCOPED_TRACE("band " + std::to_string(band) + ", transform " + std::to_string(int(transform)));
    format::Asset a = randomAsset({9}, format::WeightEncoding::Float16, transform, 7, glm::uvec3(3, 2, 2), band);
    std::vector<uint8_t> bytes = format::encode(a);
    nrad::Asset asset;
    ASSERT_EQ(asset.loadFromMemory(bytes.data(), bytes.size(), NRAD_LOAD_BORROW), NRAD_OK);
    Points pts = randomPoints(257, 11), run = coherentPoints(a, 5);
    pts.p.insert(pts.p.end(), run.p.begin(), run.p.end());
    pts.n.insert(pts.n.end(), run.n.begin(), run.n.end());
    pts.d.insert(pts.d.end(), run.d.begin(), run.d.end());
    const size_t n = pts.p.size() / 3;
    for (NradKernel kernel : kernels()) {
    ASSERT_EQ(nradSelectKernel(kernel), NRAD_OK);
    SCOPED_TRACE("kernel " + std::to_string(int(kernel)));
    std::vector<float> rgb(3 * n);
    const uint64_t blendedBefore = rt::testing::blendedBlocksSoFar();
    ASSERT_EQ(asset.evaluateBatch(n, pts.p.data(), pts.n.data(), pts.d.data(), rgb.data()), NRAD_OK);
    // The vector kernels blend coherent runs in registers (what this test holds to the general path's bits).
    if (band > 0.0f && kernel != NRAD_KERNEL_SCALAR) {
        EXPECT_GT(rt::testing::blendedBlocksSoFar(), blendedBefore);
    }
    if (kernel == NRAD_KERNEL_SCALAR) {
        EXPECT_EQ(rt::testing::blendedBlocksSoFar(), blendedBefore);
    }
    std::vector<float> soa[12];
    for (int k = 0; k < 9; ++k)
        for (size_t i = 0; i < n; ++i) soa[k].push_back((k < 3 ? pts.p : k < 6 ? pts.n : pts.d)[3 * i + size_t(k % 3)]);
    for (int k = 9; k < 12; ++k) soa[k].assign(n, -1.0f);
    std::vector<uint8_t> flags(n);
    NradBatchSoA b{soa[0].data(), soa[1].data(), soa[2].data(), soa[3].data(), soa[4].data(), soa[5].data(), soa[6].data(),
                   soa[7].data(), soa[8].data(), soa[9].data(), soa[10].data(), soa[11].data(), flags.data()};
    ASSERT_EQ(asset.evaluateBatch(n, b), NRAD_OK);
    for (size_t i = 0; i < n; ++i) {
        float one[3];
        uint32_t flag;
        ASSERT_EQ(asset.evaluate(&pts.p[3 * i], &pts.n[3 * i], &pts.d[3 * i], one, &flag), NRAD_OK);
        EXPECT_EQ(flag, flags[i]);
        for (int c = 0; c < 3; ++c) {
            EXPECT_EQ(rgb[3 * i + size_t(c)], soa[9 + c][i]);
            EXPECT_EQ(rgb[3 * i + size_t(c)], one[c]) << "point " << i;
        }
    }
    }
    nradSelectKernel(NRAD_KERNEL_AUTO);
    const char* json;
    size_t length;
    ASSERT_EQ(nradGetMetadata(asset.get(), &json, &length), NRAD_OK);
    EXPECT_EQ(std::string(json, length), "{\"test\":true}");
    }
}

// Long runs in one cell, as a rendered surface gives them: consecutive vectors share their network, which the
// kernels with 32 vector registers evaluate two at a time (evalNetworkPair); runs that end inside a pair of
// vectors (a pair over two networks), bad points among them, an odd number of vectors and a partial last one;
// on a fully occupied blended grid, vectors in one voxel reaching into bands on every side (evalBlended over up
// to 27 voxels). Every kernel's batch must give each point its bits through a single-point call, grids (blended
// or not) and kd-trees alike; a pair evaluated in any other order, or a blended term dropped, fails here.
TEST(Runtime, PairsOfVectorsInOneCellMatchSinglePoints) {
    format::Asset grid = randomAsset({9}, format::WeightEncoding::Float16, format::OutputTransform::Exponential, 31,
                                     glm::uvec3(3, 4, 2), 0.0f);
    format::Asset blended = randomAsset({9}, format::WeightEncoding::Float16, format::OutputTransform::Exponential, 32,
                                        glm::uvec3(4, 4, 4), 0.125f);
    format::Asset tree = blended;
    {  // every voxel occupied (randomAsset fills every other one), so that a run's vectors blend up to 27 networks
        const size_t per = blended.topology.parameterCount(), had = blended.voxels.size();
        std::vector<float> weights;
        blended.voxels.clear();
        for (uint32_t v = 0; v < blended.grid.voxelCount(); ++v) {
            blended.voxels.push_back({v, 0.5f + 0.01f * float(v)});
            const float* w = tree.weights.data() + (v % had) * per;
            weights.insert(weights.end(), w, w + per);
        }
        blended.weights = weights;
    }
    const std::vector<format::TreeBox> boxes = test::makeRandomTreeAsset(tree, 8, 20, 4, 5, 3);
    ASSERT_FALSE(boxes.empty());
    for (const format::Asset* source : {&grid, &blended, &tree}) {
        SCOPED_TRACE(source == &grid ? "grid" : source == &blended ? "blended grid" : "kd-tree");
        const std::vector<uint8_t> bytes = format::encode(*source);
        nrad::Asset asset;
        ASSERT_EQ(asset.loadFromMemory(bytes.data(), bytes.size()), NRAD_OK);
        const format::Grid& g = source->grid;
        std::mt19937 rng(13);
        std::uniform_real_distribution<float> u(0.0f, 1.0f), s(-1.0f, 1.0f);
        Points pts;
        while (pts.p.size() < 3 * 5000) {
            // A run of 16 m + r points in one cell: the middle of a tree's leaf box or an unblended voxel; a whole
            // blended voxel, so that its vectors reach into bands on every side (boxes of up to 27 voxels).
            const int run = 16 * int(1 + rng() % 6) + int(rng() % 3 == 0 ? rng() % 16 : 0);
            uint32_t lo[3], hi[3];
            if (source == &tree) {
                const format::TreeBox& box = boxes[rng() % boxes.size()];
                for (int k = 0; k < 3; ++k) lo[k] = box.lo[k], hi[k] = box.hi[k];
            } else {
                for (int k = 0; k < 3; ++k) lo[k] = uint32_t(rng() % g.dims[k]), hi[k] = lo[k] + 1;
            }
            for (int i = 0; i < run; ++i) {
                for (int k = 0; k < 3; ++k) {
                    const float f = source == &blended ? u(rng) : 0.2f + 0.6f * u(rng);
                    const float lattice = float(lo[k]) + f * float(hi[k] - lo[k]);
                    const float size = (g.upper[k] - g.lower[k]) / float(g.dims[k]);
                    pts.p.push_back(g.lower[k] + size * lattice);
                    pts.n.push_back(s(rng));
                    pts.d.push_back(s(rng));
                }
                if (rng() % 211 == 0) pts.d[pts.d.size() - 1] = std::numeric_limits<float>::infinity();
            }
        }
        const size_t n = pts.p.size() / 3 - 5;  // a partial last vector
        const uint64_t blendedBefore = rt::testing::blendedBlocksSoFar();
        for (NradKernel k : kernels()) {
            ASSERT_EQ(nradSelectKernel(k), NRAD_OK);
            std::vector<float> batch(3 * n), single(3 * n);
            std::vector<uint8_t> flags(n);
            ASSERT_EQ(asset.evaluateBatch(n, pts.p.data(), pts.n.data(), pts.d.data(), batch.data(), flags.data()), NRAD_OK);
            for (size_t i = 0; i < n; ++i) {
                uint32_t flag = 0;
                ASSERT_EQ(nradEvaluate(asset.get(), &pts.p[3 * i], &pts.n[3 * i], &pts.d[3 * i], &single[3 * i], &flag), NRAD_OK);
                ASSERT_EQ(uint32_t(flags[i]), flag) << "kernel " << k << " point " << i;
                ASSERT_EQ(std::memcmp(&batch[3 * i], &single[3 * i], 12), 0) << "kernel " << k << " point " << i;
            }
        }
        if (source == &blended && kernels().size() > 1) {
            EXPECT_GT(rt::testing::blendedBlocksSoFar(), blendedBefore) << "no vector was blended in registers";
        }
    }
    nradSelectKernel(NRAD_KERNEL_AUTO);
}

// The shading contract's own 2^x (the reflectance fit's exp2(-9.28 n.wo), the same bits in every kernel):
// within 3e-7 of the C library's over its whole range, exact at integers, clamped at +-125, NaN to 2^-125.
TEST(Runtime, TheContractsExp2IsAccurateAndClamped) {
    double worst = 0.0;
    for (int i = -1250000; i <= 1250000; ++i) {
        const float x = float(i) * 1e-4f;
        worst = std::max(worst, std::abs(double(eval::exp2Poly(x)) / std::exp2(double(x)) - 1.0));
    }
    EXPECT_LT(worst, 3e-7);
    for (int n = -125; n <= 125; ++n) EXPECT_EQ(eval::exp2Poly(float(n)), std::ldexp(1.0f, n)) << n;
    EXPECT_EQ(eval::exp2Poly(400.0f), std::ldexp(1.0f, 125));
    EXPECT_EQ(eval::exp2Poly(-std::numeric_limits<float>::infinity()), std::ldexp(1.0f, -125));
    EXPECT_EQ(eval::exp2Poly(std::numeric_limits<float>::quiet_NaN()), std::ldexp(1.0f, -125));
}

// Every asset the loader accepts gives finite radiance for every finite input (docs/format.md): the fuzzer's
// +inf asset (a linear output, scale 247, fp16 weights 688, evaluated with huge finite normals) and its
// relatives (the largest fp16 weights, the largest float scale, exponential outputs), through every kernel,
// every entry point and shading. Outputs are clamped to [0, eval::kMaxRadiance].
TEST(Runtime, EveryAcceptedAssetGivesFiniteOutputForFiniteInputs) {
    // A network that overflows to NaN (inf - inf inside it): exp - 1 keeps the NaN without converting it to an
    // integer (undefined behaviour, which the fuzzer found), and the decoded radiance is 0.
    const float nan = std::numeric_limits<float>::quiet_NaN();
    EXPECT_TRUE(std::isnan(eval::expMinusOne(nan)));
    EXPECT_EQ(eval::decodeOutput(format::OutputTransform::Exponential, 2.0f, nan), 0.0f);
    EXPECT_EQ(eval::decodeOutput(format::OutputTransform::ClampedLinear, 2.0f, nan), 0.0f);
    EXPECT_EQ(eval::decodeOutput(format::OutputTransform::Exponential, 3e38f, 1e30f), eval::kMaxRadiance);
    struct Case {
        format::OutputTransform transform;
        float scale, weight;
    };
    const Case cases[] = {{format::OutputTransform::ClampedLinear, 247.0f, 688.0f},
                          {format::OutputTransform::ClampedLinear, 3.0e38f, 65504.0f},
                          {format::OutputTransform::Exponential, 3.0e38f, 688.0f},
                          {format::OutputTransform::Exponential, 247.0f, -65504.0f}};
    std::mt19937 rng(17);
    std::uniform_real_distribution<float> u(-1.0f, 1.0f);
    for (const Case& c : cases) {
        format::Asset a = randomAsset({9}, format::WeightEncoding::Float16, c.transform, 2, glm::uvec3(2, 2, 2), 0.25f);
        for (size_t i = 0; i < a.weights.size(); ++i) a.weights[i] = i % 3 == 0 ? -c.weight : c.weight;
        for (format::VoxelEntry& v : a.voxels) v.scale = c.scale;
        a.header.flags |= format::kFlagScatteredRadiance | format::kFlagDemodulated;
        const std::vector<uint8_t> bytes = format::encode(a);
        nrad::Asset asset;
        ASSERT_EQ(asset.loadFromMemory(bytes.data(), bytes.size()), NRAD_OK);
        // Inside the grid (blended and not), inputs from unit length up to 1e38 in magnitude.
        Points pts;
        std::vector<NradSurface> surfaces;
        for (int i = 0; i < 4096; ++i) {
            const float magnitude = std::pow(10.0f, 38.0f * float(i % 64) / 63.0f);
            for (int k = 0; k < 3; ++k) {
                pts.p.push_back(a.grid.lower[k] + (a.grid.upper[k] - a.grid.lower[k]) * (0.5f + 0.499f * u(rng)));
                pts.n.push_back(u(rng) * magnitude);
                pts.d.push_back(u(rng) * (i % 2 ? magnitude : 1.0f));
            }
            surfaces.push_back({{1.0f, 1.0f, 1.0f}, 0.0f, 0.5f, i % 5 ? 1.0f : 1e30f, {1.0f, 2.0f, 3.0f}});
        }
        const size_t n = surfaces.size();
        for (NradKernel k : kernels()) {
            ASSERT_EQ(nradSelectKernel(k), NRAD_OK);
            std::vector<float> batch(3 * n), shaded(3 * n), soa(3 * n);
            ASSERT_EQ(asset.evaluateBatch(n, pts.p.data(), pts.n.data(), pts.d.data(), batch.data()), NRAD_OK);
            ASSERT_EQ(asset.shadeBatch(n, pts.p.data(), pts.n.data(), pts.d.data(), surfaces.data(), shaded.data()), NRAD_OK);
            std::vector<float> px(n), py(n), pz(n), nx(n), ny(n), nz(n), dx(n), dy(n), dz(n), r(n), g(n), b(n);
            for (size_t i = 0; i < n; ++i) {
                px[i] = pts.p[3 * i], py[i] = pts.p[3 * i + 1], pz[i] = pts.p[3 * i + 2];
                nx[i] = pts.n[3 * i], ny[i] = pts.n[3 * i + 1], nz[i] = pts.n[3 * i + 2];
                dx[i] = pts.d[3 * i], dy[i] = pts.d[3 * i + 1], dz[i] = pts.d[3 * i + 2];
            }
            NradBatchSoA s{px.data(), py.data(), pz.data(), nx.data(), ny.data(), nz.data(), dx.data(), dy.data(), dz.data(),
                           r.data(), g.data(), b.data(), nullptr};
            ASSERT_EQ(asset.evaluateBatch(n, s), NRAD_OK);
            size_t clamped = 0;
            for (size_t i = 0; i < n; ++i) {
                float one[3];
                ASSERT_EQ(asset.evaluate(&pts.p[3 * i], &pts.n[3 * i], &pts.d[3 * i], one), NRAD_OK);
                for (int ch = 0; ch < 3; ++ch) {
                    const float v[4] = {batch[3 * i + size_t(ch)], shaded[3 * i + size_t(ch)], one[ch], (ch == 0 ? r : ch == 1 ? g : b)[i]};
                    for (float x : v) ASSERT_TRUE(std::isfinite(x) && x >= 0.0f) << "kernel " << k << " point " << i << ": " << x;
                    EXPECT_LE(batch[3 * i + size_t(ch)], eval::kMaxRadiance * 1.000001f);
                    clamped += batch[3 * i + size_t(ch)] >= 0.999f * eval::kMaxRadiance;
                }
            }
            if (c.scale > 1e37f) {
                EXPECT_GT(clamped, 0u) << "the case must reach the bound";
            }
        }
    }
    nradSelectKernel(NRAD_KERNEL_AUTO);
}

// AUTO picks the widest kernel this CPU runs: NEON on 64-bit ARM (run under qemu by
// tests/runtime_standalone/run.sh aarch64), AVX-512 or AVX2 on x86-64, and a kernel the CPU lacks is refused.
TEST(Runtime, TheBestKernelOfThisCpuIsChosen) {
    ASSERT_EQ(nradSelectKernel(NRAD_KERNEL_AUTO), NRAD_OK);
#if defined(__aarch64__)
    EXPECT_EQ(nradActiveKernel(), NRAD_KERNEL_NEON);
    EXPECT_EQ(nradKernelSupported(NRAD_KERNEL_AVX2), 0);
    EXPECT_EQ(nradSelectKernel(NRAD_KERNEL_AVX2), NRAD_ERROR_UNSUPPORTED_KERNEL);
#else
    EXPECT_EQ(nradKernelSupported(NRAD_KERNEL_NEON), 0);
    EXPECT_EQ(nradSelectKernel(NRAD_KERNEL_NEON), NRAD_ERROR_UNSUPPORTED_KERNEL);
    EXPECT_EQ(nradActiveKernel(), nradKernelSupported(NRAD_KERNEL_AVX512) ? NRAD_KERNEL_AVX512
                                  : nradKernelSupported(NRAD_KERNEL_AVX2) ? NRAD_KERNEL_AVX2
                                                                          : NRAD_KERNEL_SCALAR);
#endif
    EXPECT_EQ(nradSelectKernel(NradKernel(99)), NRAD_ERROR_INVALID_ARGUMENT);
}

// One asset's kernel, whatever the process-wide choice: an asset pinned to the scalar kernel gives the scalar
// kernel's bits while the process runs its fastest, and follows the process again with AUTO.
TEST(Runtime, KernelChoicePerAsset) {
    format::Asset a = randomAsset({9}, format::WeightEncoding::Float16, format::OutputTransform::Exponential, 12,
                                  glm::uvec3(3, 3, 3), 0.125f);
    const std::vector<uint8_t> bytes = format::encode(a);
    nrad::Asset pinned, free;
    ASSERT_EQ(pinned.loadFromMemory(bytes.data(), bytes.size()), NRAD_OK);
    ASSERT_EQ(free.loadFromMemory(bytes.data(), bytes.size()), NRAD_OK);
    const Points pts = randomPoints(4000, 8);
    const size_t n = pts.p.size() / 3;
    auto run = [&](const nrad::Asset& asset) {
        std::vector<float> rgb(3 * n);
        EXPECT_EQ(asset.evaluateBatch(n, pts.p.data(), pts.n.data(), pts.d.data(), rgb.data()), NRAD_OK);
        return rgb;
    };
    ASSERT_EQ(nradSelectKernel(NRAD_KERNEL_SCALAR), NRAD_OK);
    const std::vector<float> scalar = run(free);
    ASSERT_EQ(nradSelectKernel(NRAD_KERNEL_AUTO), NRAD_OK);
    const std::vector<float> fastest = run(free);
    ASSERT_EQ(nradSetAssetKernel(pinned.get(), NRAD_KERNEL_SCALAR), NRAD_OK);
    EXPECT_EQ(run(pinned), scalar);
    EXPECT_EQ(run(free), fastest);
    ASSERT_EQ(nradSetAssetKernel(pinned.get(), NRAD_KERNEL_AUTO), NRAD_OK);
    EXPECT_EQ(run(pinned), fastest);
    if (nradActiveKernel() != NRAD_KERNEL_SCALAR) {
        EXPECT_NE(scalar, fastest) << "the kernels must differ for this test to mean anything";
    }
    EXPECT_EQ(nradSetAssetKernel(pinned.get(), NradKernel(42)), NRAD_ERROR_INVALID_ARGUMENT);
    EXPECT_EQ(nradSetAssetKernel(nullptr, NRAD_KERNEL_SCALAR), NRAD_ERROR_INVALID_ARGUMENT);
    for (NradKernel k : {NRAD_KERNEL_AVX2, NRAD_KERNEL_AVX512, NRAD_KERNEL_NEON})
        EXPECT_EQ(nradSetAssetKernel(pinned.get(), k), nradKernelSupported(k) ? NRAD_OK : NRAD_ERROR_UNSUPPORTED_KERNEL);
}

TEST(Runtime, FlagsForOutsideEmptyAndInvalidPoints) {
    format::Asset a = randomAsset({9}, format::WeightEncoding::Float32, format::OutputTransform::ClampedLinear, 3);
    std::vector<uint8_t> bytes = format::encode(a);
    nrad::Asset asset;
    ASSERT_EQ(asset.loadFromMemory(bytes.data(), bytes.size()), NRAD_OK);
    const float n[3] = {0, 0, 1}, d[3] = {0, 0, 1};
    float rgb[3] = {7, 7, 7};
    uint32_t flag = 99;
    const float outside[3] = {100.0f, 0.0f, 0.0f};
    EXPECT_EQ(asset.evaluate(outside, n, d, rgb, &flag), NRAD_OK);
    EXPECT_EQ(flag, uint32_t(NRAD_POINT_OUTSIDE_GRID));
    EXPECT_EQ(rgb[0], 0.0f);
    // Voxel 1 (x = 1, y = 0, z = 0) is empty: only even voxels have networks.
    const float empty[3] = {-1.0f + 1.5f, -2.0f + 0.1f, -3.0f + 0.1f};
    EXPECT_EQ(asset.evaluate(empty, n, d, rgb, &flag), NRAD_OK);
    EXPECT_EQ(flag, uint32_t(NRAD_POINT_EMPTY_VOXEL));
    const float nan[3] = {std::nanf(""), 0.0f, 0.0f};
    EXPECT_EQ(asset.evaluate(nan, n, d, rgb, &flag), NRAD_OK);
    EXPECT_EQ(flag, uint32_t(NRAD_POINT_INVALID_INPUT));
    EXPECT_EQ(rgb[1], 0.0f);
    EXPECT_EQ(nradEvaluate(nullptr, n, n, d, rgb, &flag), NRAD_ERROR_INVALID_ARGUMENT);
    EXPECT_EQ(nradEvaluate(asset.get(), nullptr, n, d, rgb, &flag), NRAD_ERROR_INVALID_ARGUMENT);
    EXPECT_EQ(nradEvaluateBatch(asset.get(), 0, nullptr, nullptr, nullptr, nullptr, nullptr), NRAD_OK);
    EXPECT_STREQ(nradStatusString(NRAD_ERROR_CORRUPT), "the asset is damaged (checksum or structure)");
}

TEST(Runtime, ConcurrentEvaluationOnASharedHandle) {
    format::Asset a = randomAsset({9}, format::WeightEncoding::Float16, format::OutputTransform::Exponential, 13);
    std::vector<uint8_t> bytes = format::encode(a);
    nrad::Asset asset;
    ASSERT_EQ(asset.loadFromMemory(bytes.data(), bytes.size()), NRAD_OK);
    const size_t n = 5000;
    Points pts = randomPoints(n, 17);
    std::vector<float> expected(3 * n);
    ASSERT_EQ(asset.evaluateBatch(n, pts.p.data(), pts.n.data(), pts.d.data(), expected.data()), NRAD_OK);
    std::vector<std::vector<float>> results(4, std::vector<float>(3 * n));
    std::vector<std::thread> threads;
    for (int t = 0; t < 4; ++t)
        threads.emplace_back([&, t] {
            for (int rep = 0; rep < 20; ++rep)
                asset.evaluateBatch(n, pts.p.data(), pts.n.data(), pts.d.data(), results[size_t(t)].data());
        });
    for (std::thread& t : threads) t.join();
    for (const auto& r : results) EXPECT_EQ(r, expected);
}

NradStatus loadStatus(const std::vector<uint8_t>& b) {
    NradAsset a = nullptr;
    char message[128];
    NradStatus s = nradLoadFromMemory(b.data(), b.size(), NRAD_LOAD_COPY, &a, message, sizeof message);
    if (s == NRAD_OK) EXPECT_NE(a, nullptr); else EXPECT_EQ(a, nullptr);
    nradReleaseAsset(a);
    return s;
}

// Rewrites the CRCs after a deliberate change, so the loader sees a well-formed but hostile file.
void fixCrcs(std::vector<uint8_t>& b) {
    auto rd32 = [&](size_t at) { return uint32_t(b[at]) | uint32_t(b[at + 1]) << 8 | uint32_t(b[at + 2]) << 16 | uint32_t(b[at + 3]) << 24; };
    auto wr32 = [&](size_t at, uint32_t v) { for (int i = 0; i < 4; ++i) b[at + size_t(i)] = uint8_t(v >> (8 * i)); };
    // The planted values may be huge: only records and sections inside the buffer get their CRC fixed.
    uint64_t sections = rd32(20);
    for (uint64_t i = 0; i < sections && 64 + 32 * (i + 1) <= b.size(); ++i) {
        size_t r = 64 + 32 * size_t(i);
        uint64_t off = rd32(r + 8), size = rd32(r + 16) | uint64_t(rd32(r + 20)) << 32;
        if (off <= b.size() && size <= b.size() - off) wr32(r + 24, format::crc32(b.data() + off, size_t(size)));
    }
    if (64 + 32 * sections <= b.size()) wr32(40, format::crc32(b.data() + 64, size_t(32 * sections)));
    wr32(60, format::crc32(b.data(), 60));
}

TEST(RuntimeLoader, HostileAndDamagedBytes) {
    format::Asset a = randomAsset({9}, format::WeightEncoding::Float16, format::OutputTransform::Exponential, 1);
    std::vector<uint8_t> good = format::encode(a);
    EXPECT_EQ(loadStatus(good), NRAD_OK);
    for (size_t n = 0; n < good.size(); ++n) {
        std::vector<uint8_t> prefix(good.begin(), good.begin() + long(n));
        NradStatus s = loadStatus(prefix);
        ASSERT_TRUE(s == NRAD_ERROR_TRUNCATED || (n < 64 && s == NRAD_ERROR_NOT_AN_ASSET)) << n << " " << s;
    }
    for (size_t i = 0; i < good.size(); ++i) {
        std::vector<uint8_t> b = good;
        b[i] ^= 0x5A;
        ASSERT_NE(loadStatus(b), NRAD_OK) << "byte " << i;
    }
    std::vector<uint8_t> b = good;
    b[1] = 'X';
    EXPECT_EQ(loadStatus(b), NRAD_ERROR_NOT_AN_ASSET);
    b = good;
    b[8] = 3;
    EXPECT_EQ(loadStatus(b), NRAD_ERROR_UNSUPPORTED_VERSION);
    {  // a version 1 asset (networks storing L with emission), as docs/format.md promises
        std::ifstream f(test::sourcePath("tests/data/golden/tiny-v1.nrad"), std::ios::binary);
        std::vector<uint8_t> v1((std::istreambuf_iterator<char>(f)), std::istreambuf_iterator<char>());
        ASSERT_FALSE(v1.empty());
        EXPECT_EQ(loadStatus(v1), NRAD_ERROR_UNSUPPORTED_VERSION);
    }
    b = good;
    b.push_back(0);
    EXPECT_EQ(loadStatus(b), NRAD_ERROR_CORRUPT);
    // Huge counts with valid CRCs: occupied voxels, section sizes, hidden widths, grid dimensions.
    const size_t voxl = 64 + 32 * 2;  // VOXL's record
    auto sectionOffset = [&](size_t record) { return size_t(good[record + 8]) | size_t(good[record + 9]) << 8; };
    b = good;
    b[sectionOffset(voxl) + 3] = 0x7F;  // occupiedCount ~ 2^31
    fixCrcs(b);
    EXPECT_EQ(loadStatus(b), NRAD_ERROR_INVALID_CONTENT);
    b = good;
    b[64 + 32 * 3 + 16 + 7] = 0x40;  // WGHT size ~ 2^62
    fixCrcs(b);
    EXPECT_NE(loadStatus(b), NRAD_OK);
    b = good;
    b[sectionOffset(64 + 32) + 24 + 3] = 0x10;  // hidden width 2^28
    fixCrcs(b);
    EXPECT_EQ(loadStatus(b), NRAD_ERROR_INVALID_CONTENT);
    b = good;
    b[sectionOffset(64) + 24 + 3] = 0xFF;  // grid dims ~ 4e9
    fixCrcs(b);
    EXPECT_EQ(loadStatus(b), NRAD_ERROR_INVALID_CONTENT);
    b = good;
    b[20] = 0xFF;  // 255 sections
    fixCrcs(b);
    EXPECT_NE(loadStatus(b), NRAD_OK);
    // Null arguments and missing files.
    NradAsset h = nullptr;
    EXPECT_EQ(nradLoadFromMemory(nullptr, 10, 0, &h, nullptr, 0), NRAD_ERROR_INVALID_ARGUMENT);
    EXPECT_EQ(nradLoadFromMemory(good.data(), good.size(), 0, nullptr, nullptr, 0), NRAD_ERROR_INVALID_ARGUMENT);
    char message[256];
    EXPECT_EQ(nradLoadFromFile("/nonexistent.nrad", &h, message, sizeof message), NRAD_ERROR_IO);
    EXPECT_STREQ(message, "/nonexistent.nrad: cannot open file");
}


}  // namespace
}  // namespace nrad
