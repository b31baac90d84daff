// The adaptive partition (nrad bake --budget): the asset never exceeds its budget, is byte-identical for one
// and two threads, and refines where the error is: a plane with one sharp shadow gets its small leaves at the
// shadow's edges, not on the evenly lit rest.
#include "baker/bake/baker.h"

#include <algorithm>
#include <cmath>
#include <functional>

#include <gtest/gtest.h>
#include <nrad/nrad.hpp>

#include "baker/scene/gltf_loader.h"
#include "baker/util/threads.h"
#include "support/test_paths.h"
#include "support/test_scenes.h"

namespace nrad {
namespace {

BakeSettings tinySettings(uint64_t budget) {
    BakeSettings s;
    s.partition.budgetBytes = budget;
    s.partition.minLeafSamples = 64;
    s.samples.points = 12000;
    s.samples.paths = 4;
    s.train.epochs = 40;
    s.train.patience = 20;
    s.train.weightDecays = {0.0f};
    s.samples.seed = s.train.seed = 3;
    return s;
}

TEST(Partition, TheBudgetIsNeverExceeded) {
    Scene scene = loadGltf(test::sourcePath("scenes/cornell-box/cornell-box.gltf"));
    size_t previous = 0;
    for (uint64_t budget : {1200u, 3000u, 6000u, 14000u}) {
        const BakeResult r = bakeScene(scene, tinySettings(budget));
        const std::vector<uint8_t> bytes = format::encode(r.asset);
        EXPECT_LE(bytes.size(), budget);
        EXPECT_EQ(bytes.size(), format::encodedSize(r.asset.topology, r.asset.voxels.size(), r.asset.tree.size(), r.asset.metadata.size()));
        // The budget is spent, not left: within one more split (a network, its entry, two nodes), or no split
        // was left to make.
        const uint64_t perSplit = 8 + 16 + r.asset.topology.parameterCount() * 2;
        EXPECT_TRUE(bytes.size() + perSplit > budget || r.partition.splitsSkippedForBudget == 0) << budget;
        EXPECT_EQ(bytes.size(), r.partition.bytes);  // the refinement counted every byte
        EXPECT_GT(bytes.size(), previous);
        previous = bytes.size();
        format::Asset back;
        ASSERT_EQ(format::decode(bytes.data(), bytes.size(), back), format::DecodeStatus::Ok);
        EXPECT_EQ(back.leafCount, r.partition.leafCount);
        EXPECT_EQ(r.voxels.size(), r.partition.networks);
    }
    // Below one network's asset: refused, naming the smallest budget.
    try {
        bakeScene(scene, tinySettings(300));
        ADD_FAILURE() << "a budget of 300 bytes was accepted";
    } catch (const std::runtime_error& e) {
        EXPECT_NE(std::string(e.what()).find("smallest asset"), std::string::npos) << e.what();
    }
}

// Training within the integral equation adds samples after the partition is set (the metadata counts them):
// the budget still holds, and the rounds keep to the tree's leaves.
TEST(Partition, TheBudgetHoldsWithIntegralTraining) {
    Scene scene = loadGltf(test::sourcePath("scenes/cornell-box/cornell-box.gltf"));
    for (uint64_t budget : {3000u, 14000u}) {
        BakeSettings s = tinySettings(budget);
        s.training = TrainingMethod::Integral;
        s.integral.generations = 2;
        s.integral.points = 120000;  // more samples than the start: the count gains a digit
        const BakeResult r = bakeScene(scene, s);
        const std::vector<uint8_t> bytes = format::encode(r.asset);
        EXPECT_LE(bytes.size(), budget);
        EXPECT_GT(r.sampleCount, 200000u);
        EXPECT_NE(r.asset.metadata.find("\"samples\":" + std::to_string(r.sampleCount)), std::string::npos);
        EXPECT_EQ(r.voxels.size(), r.partition.networks);
        format::Asset back;
        ASSERT_EQ(format::decode(bytes.data(), bytes.size(), back), format::DecodeStatus::Ok);
    }
}

TEST(Partition, ByteIdenticalForOneAndTwoThreads) {
    Scene scene = loadGltf(test::sourcePath("scenes/cornell-box-glossy/cornell-box-glossy.gltf"));
    BakeSettings s = tinySettings(5000);
    s.samples.points = 4000;
    EXPECT_EQ(test::bakeBytes(scene, s, 1), test::bakeBytes(scene, s, 2));
}

// A white plane 20 x 20 under a sharp sun straight above, and a bar 0.5 wide floating 2 above it across the
// whole plane: one shadow strip x in [1, 1.5] with sharp edges, evenly lit everywhere else.
Scene shadowScene() {
    Scene scene = test::makeLitPlane(0.5f, 10.0f);
    TriangleMesh& mesh = scene.mesh;
    const uint32_t base = uint32_t(mesh.positions.size());
    for (glm::vec2 c : {glm::vec2(1.0f, -10.0f), glm::vec2(1.5f, -10.0f), glm::vec2(1.5f, 10.0f), glm::vec2(1.0f, 10.0f)}) {
        mesh.positions.emplace_back(c.x, c.y, 2.0f);
        mesh.normals.emplace_back(0, 0, 1);
        mesh.uv0.emplace_back(0.0f);
        mesh.uv1.emplace_back(0.0f);
    }
    mesh.triangles.push_back({base, base + 1, base + 2});
    mesh.triangles.push_back({base, base + 2, base + 3});
    mesh.materialIds.push_back(0);
    mesh.materialIds.push_back(0);
    scene.materials[0].doubleSided = true;
    PunctualLight sun;
    sun.type = PunctualLight::Type::Directional;
    sun.name = "sun";
    sun.direction = glm::vec3(0.0f, 0.0f, -1.0f);
    sun.intensity = glm::vec3(3.0f);
    scene.lights.push_back(sun);
    scene.updateBounds();
    return scene;
}

TEST(Partition, RefinesAtASharpShadow) {
    const Scene scene = shadowScene();
    BakeSettings s = tinySettings(9000);
    s.samples.points = 20000;
    const BakeResult r = bakeScene(scene, s);
    const AdaptivePartition& ap = r.partition;
    ASSERT_GT(ap.networks, 8u);
    const format::Grid& g = r.asset.grid;
    // The x extent (in world units) of the leaf holding a point of the plane.
    auto extentAt = [&](float x, float y) {
        const float p[3] = {x, y, 0.0f};
        const eval::Partition part(r.asset);
        const int64_t leaf = part.cellOf(p);
        EXPECT_GE(leaf, 0);
        const format::TreeBox& b = ap.leaves[size_t(leaf)].box;
        return float(b.hi[0] - b.lo[0]) / eval::gridFactor(g, 0);
    };
    // At both edges of the shadow, anywhere along them, the leaves are far narrower than on the lit plane
    // far from it.
    for (float y : {-7.0f, 0.3f, 6.0f}) {
        const float far = std::min(extentAt(-7.0f, y), extentAt(7.5f, y));
        EXPECT_LE(extentAt(1.0f, y), far / 4.0f) << y;
        EXPECT_LE(extentAt(1.5f, y), far / 4.0f) << y;
    }
    // And the narrowest leaves across the shadow's edges are at the shadow: every leaf with samples whose x extent is
    // the smallest touches x in [0, 2.5]. (Not the deepest: a leaf's depth also counts the splits along z, between the
    // plane and the occluder, which a finer lattice makes more of.)
    uint32_t narrowest = UINT32_MAX;
    for (const PartitionLeafInfo& l : ap.leaves)
        if (l.samples > 0) narrowest = std::min(narrowest, l.box.hi[0] - l.box.lo[0]);
    for (const PartitionLeafInfo& l : ap.leaves) {
        if (l.box.hi[0] - l.box.lo[0] != narrowest || l.samples == 0) continue;
        const float lo = g.lower[0] + float(l.box.lo[0]) / eval::gridFactor(g, 0);
        const float hi = g.lower[0] + float(l.box.hi[0]) / eval::gridFactor(g, 0);
        EXPECT_TRUE(hi > 0.0f && lo < 2.5f) << lo << " " << hi;
    }
}


// Walls inside a grid's cell (issue 38): a floor lit on one side of a 2 cm wall and dark on the other, in one
// cell; the cell is split at a plane inside the wall, so that no network holds both sides.
std::vector<TrainingSample> floorSamples(const std::function<float(float)>& radianceAt, float gapLo, float gapHi) {
    std::vector<TrainingSample> out;
    uint32_t state = 12345;
    auto next = [&] {
        state = state * 1664525u + 1013904223u;
        return float(state >> 8) * 0x1p-24f;
    };
    while (out.size() < 6000) {
        TrainingSample t;
        t.position = glm::vec3(next(), 0.0f, next());
        if (t.position.x >= gapLo && t.position.x <= gapHi) continue;  // inside the wall: no surface
        t.normal = glm::vec3(0, 1, 0);
        t.wo = glm::normalize(glm::vec3(next() - 0.5f, 1.0f, next() - 0.5f));
        t.radiance = glm::vec3(radianceAt(t.position.x));
        t.voxel = 0;
        out.push_back(t);
    }
    return out;
}

std::vector<float> learnedOf(const std::vector<TrainingSample>& samples) {
    std::vector<float> learned;
    for (const TrainingSample& t : samples) learned.push_back(std::log(t.radiance.y + 0.1f));
    return learned;
}

format::Grid unitGrid() {
    format::Grid g;
    g.lower[1] = -0.5f;
    g.upper[1] = 0.5f;
    return g;
}

TEST(Walls, AGridCellIsSplitInsideAThinWallBetweenALitAndADarkSide) {
    const std::vector<TrainingSample> samples = floorSamples([](float x) { return x < 0.41f ? 1.0f : 0.03f; }, 0.40f, 0.42f);
    const format::Grid g = unitGrid();
    const AdaptivePartition ap = splitWalls(g, samples, learnedOf(samples), WallSplitSettings{});
    ASSERT_EQ(ap.leafCount, 2u);
    ASSERT_EQ(ap.tree.size(), 3u);
    EXPECT_EQ(ap.tree[0].axis, 0u);
    const float plane = float(ap.tree[0].split) / float(wallRefine(g));  // world x (the box is [0, 1])
    EXPECT_GE(plane, 0.40f);
    EXPECT_LE(plane, 0.42f);
    // Every sample in the leaf on its side of the wall.
    for (size_t i = 0; i < samples.size(); ++i) EXPECT_EQ(ap.leafOfSample[i], samples[i].position.x < 0.41f ? 0u : 1u) << i;
    // The plane lies in the wall, 5 lattice voxels from any surface: hard, no band across it.
    EXPECT_TRUE(ap.tree[0].hard);
    // The same step of light on a floor that runs on through the plane (a shadow's edge, no wall): split, but soft.
    const std::vector<TrainingSample> floor = floorSamples([](float x) { return x < 0.41f ? 1.0f : 0.03f; }, 2.0f, 2.0f);
    const AdaptivePartition edge = splitWalls(g, floor, learnedOf(floor), WallSplitSettings{});
    ASSERT_EQ(edge.leafCount, 2u);
    EXPECT_FALSE(edge.tree[0].hard);
    WallSplitSettings soft;
    soft.hardGap = 0.0f;
    EXPECT_FALSE(splitWalls(g, samples, learnedOf(samples), soft).tree[0].hard);
    // Off: the grid stays whole.
    WallSplitSettings off;
    off.minGainPerSample = 1e9;
    EXPECT_EQ(splitWalls(g, samples, learnedOf(samples), off).leafCount, 1u);
}

TEST(Walls, SmoothLightIsLeftWhole) {
    // Light falling off smoothly across the cell (a factor of 4, not linear in x): no split.
    const std::vector<TrainingSample> smooth = floorSamples([](float x) { return 1.0f / (1.0f + 3.0f * x * x); }, 2.0f, 2.0f);
    EXPECT_EQ(splitWalls(unitGrid(), smooth, learnedOf(smooth), WallSplitSettings{}).leafCount, 1u);
    // A step of 20% (no wall, a soft feature): no split either.
    const std::vector<TrainingSample> soft = floorSamples([](float x) { return x < 0.5f ? 1.0f : 0.8f; }, 2.0f, 2.0f);
    EXPECT_EQ(splitWalls(unitGrid(), soft, learnedOf(soft), WallSplitSettings{}).leafCount, 1u);
}

TEST(Walls, TheDoorwayRoomsAreSplitAtTheirWallAndTheBoxesNowhere) {
    // The bundled boxes have no wall inside a cell: their defaults bake the plain grid, byte for byte as without.
    BakeSettings s;
    s.samples.points = 40000;
    s.samples.paths = 4;
    s.train.epochs = 20;
    s.train.patience = 10;
    s.train.weightDecays = {0.0f};
    {
        const Scene box = loadGltf(test::sourcePath("scenes/cornell-box/cornell-box.gltf"));
        const BakeResult on = bakeScene(box, s);
        EXPECT_EQ(on.asset.header.flags & format::kFlagTree, 0u);
        BakeSettings noWalls = s;
        noWalls.walls.enabled = false;
        EXPECT_EQ(format::encode(on.asset), format::encode(bakeScene(box, noWalls).asset));
    }
    // Two rooms sharing a wall at x in [2.22, 2.24] m: the cells the wall crosses are split inside it, and every
    // leaf lies on one side.
    const Scene rooms = loadGltf(test::sourcePath("scenes/doorway-rooms/doorway-rooms.gltf"));
    const BakeResult r = bakeScene(rooms, s);
    ASSERT_NE(r.asset.header.flags & format::kFlagTree, 0u);
    const format::Grid& g = r.asset.grid;
    EXPECT_GT(r.partition.leafCount, 27u);
    int wallPlanes = 0;
    for (const format::TreeNode& n : r.asset.tree) {
        if (n.axis != 0) continue;
        const float x = g.lower[0] + float(n.split) / eval::gridFactor(g, 0);
        if (n.split % (g.dims[0] / 3) == 0) continue;  // the grid's own planes
        EXPECT_GE(x, 2.215f);
        EXPECT_LE(x, 2.245f);
        ++wallPlanes;
    }
    EXPECT_GE(wallPlanes, 3);
    EXPECT_NE(r.asset.metadata.find("\"grid-walls\""), std::string::npos);
}

}  // namespace
}  // namespace nrad
