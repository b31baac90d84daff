// Light selection for NEE (issue 6): light groups, the candidate test, the network's gradient against finite
// differences, unbiasedness of learned selection against a uniform reference, learning visibility in the
// split-rooms scene, and byte-identical results for one and two threads.
#include <algorithm>
#include <cmath>
#include <cstring>
#include <random>

#include <gtest/gtest.h>

#include "baker/render/accel.h"
#include "baker/lights/light_sampler.h"
#include "baker/lights/light_selection.h"
#include "baker/render/online_render.h"
#include "baker/render/path_tracer.h"
#include "baker/render/surface.h"
#include "baker/scene/gltf_loader.h"
#include "baker/nn/adam.h"
#include "baker/util/threads.h"
#include "support/test_paths.h"
#include "support/test_scenes.h"

namespace nrad {
namespace {

Scene splitRooms() { return loadGltf(test::sourcePath("scenes/split-rooms/split-rooms.gltf")); }

// The branch-free pick against std::upper_bound (clamped to the last interval), on random CDFs with empty
// intervals, at their exact steps, at 1 and at NaN.
TEST(LightPick, CdfIntervalIsUpperBoundClamped) {
    std::mt19937 rng(7);
    size_t differing = 0, total = 0;
    for (int trial = 0; trial < 2000; ++trial) {
        std::vector<double> cdf(1 + rng() % 40);
        double sum = 0.0;
        for (double& c : cdf) c = sum += rng() % 4 == 0 ? 0.0 : double(rng() % 100);
        for (double& c : cdf) c = sum > 0.0 ? c / sum : 1.0;
        cdf.back() = 1.0;
        std::vector<float> us = {std::nanf(""), 1.0f, 0.0f, -1.0f};
        for (double c : cdf) us.push_back(float(c));
        for (int k = 0; k < 64; ++k) us.push_back(float(rng() >> 8) * 0x1p-24f);
        for (float u : us) {
            const size_t expected = std::min(size_t(std::upper_bound(cdf.begin(), cdf.end(), double(u)) - cdf.begin()),
                                             cdf.size() - 1);
            differing += cdfInterval(cdf, u) != expected;
            ++total;
        }
    }
    EXPECT_EQ(differing, 0u) << "of " << total;
    EXPECT_EQ(cdfInterval({0.25, 0.25, 1.0}, 0.25f), 2u);  // an empty interval is never picked
    EXPECT_EQ(cdfInterval({0.25, 0.5, 1.0}, 0.2f), 0u);
}

TEST(LightGroups, QuadsAreOneLightEach) {
    Scene cornell = loadGltf(test::sourcePath("scenes/cornell-box/cornell-box.gltf"));
    LightSampler one(cornell);
    EXPECT_EQ(one.lightCount(), 2u);  // two triangles
    EXPECT_EQ(one.groupCount(), 1u);  // one quad light
    Scene rooms = splitRooms();
    LightSampler eight(rooms);
    EXPECT_EQ(eight.lightCount(), 16u);
    ASSERT_EQ(eight.groupCount(), 8u);
    for (size_t i = 0; i < eight.lightCount(); ++i) EXPECT_EQ(eight.groupOfEntry(i), i / 2);
}

TEST(LightGroups, ManyLightsAreClusteredAndEveryEntryBelongsToOneGroup) {
    // 100 separate emissive triangles on a line: more than kMaxLightGroups lights.
    Scene scene;
    scene.materials.resize(1);
    scene.materials[0].emission = glm::vec3(1.0f);
    for (int i = 0; i < 100; ++i) {
        uint32_t b = uint32_t(scene.mesh.positions.size());
        float x = float(i);
        for (glm::vec3 p : {glm::vec3(x, 0, 0), glm::vec3(x + 0.5f, 0, 0), glm::vec3(x, 0, 0.5f)}) {
            scene.mesh.positions.push_back(p);
            scene.mesh.normals.push_back(glm::vec3(0, 1, 0));
            scene.mesh.uv0.push_back(glm::vec2(0));
            scene.mesh.uv1.push_back(glm::vec2(0));
        }
        scene.mesh.triangles.push_back(glm::uvec3(b, b + 1, b + 2));
        scene.mesh.materialIds.push_back(0);
    }
    scene.updateBounds();
    LightSampler lights(scene);
    ASSERT_EQ(lights.groupCount(), LightSampler::kMaxLightGroups);
    std::vector<int> count(lights.groupCount(), 0);
    double power = 0.0;
    for (size_t i = 0; i < lights.lightCount(); ++i) ++count[lights.groupOfEntry(i)];
    for (size_t g = 0; g < lights.groupCount(); ++g) {
        EXPECT_GE(count[g], 1);
        EXPECT_LE(count[g], 2);  // median splits: balanced
        power += lights.groupPower(g);
    }
    EXPECT_NEAR(power, lights.totalPower(), 1e-9 * power);
    // Spatial: the lights of a group are neighbours.
    for (size_t i = 0; i + 1 < lights.lightCount(); ++i)
        EXPECT_LE(lights.groupOfEntry(i), lights.groupOfEntry(i + 1));
}

TEST(LightGroups, CandidateTestNeverDropsALightThatContributes) {
    Scene scene = splitRooms();
    Accel accel(scene);
    LightSampler lights(scene);
    SplitMix64 rng(7);
    int checked = 0, culled = 0;
    for (int i = 0; i < 4000; ++i) {
        // A random surface point: trace a ray from a random point inside the block.
        glm::vec3 o = scene.bounds.lower + glm::vec3(rng.uniform(), rng.uniform(), rng.uniform()) * scene.bounds.extent();
        float z = 2.0f * rng.uniform() - 1.0f, phi = 6.2831853f * rng.uniform(), r = std::sqrt(1.0f - z * z);
        glm::vec3 d(r * std::cos(phi), r * std::sin(phi), z);
        Hit hit = accel.intersect(o, d);
        if (!hit.valid()) continue;
        SurfaceInteraction si = makeInteraction(scene, hit, d);
        for (size_t g = 0; g < lights.groupCount(); ++g) {
            bool candidate = lights.groupCanContribute(g, si.p, si.ng);
            ASSERT_EQ(candidate, bool(lights.candidateGroups(si.p, si.ng) >> g & 1u));  // the mask agrees
            culled += !candidate;
            for (int k = 0; k < 8; ++k) {
                LightSample ls = lights.sampleGroup(g, si.p, glm::vec2(rng.uniform(), rng.uniform()));
                bool contributes = ls.pdf > 0.0f && glm::dot(ls.wi, si.ng) > 0.0f &&
                                   (ls.Li.x > 0.0f || ls.Li.y > 0.0f || ls.Li.z > 0.0f);
                if (contributes) {
                    ++checked;
                    ASSERT_TRUE(candidate) << "group " << g << " at (" << si.p.x << ", " << si.p.y << ", " << si.p.z << ")";
                }
            }
        }
    }
    EXPECT_GT(checked, 1000);
    EXPECT_GT(culled, 100);  // the test does cull somewhere (walls facing away from lights)
}

TEST(NeeNetwork, GradientMatchesFiniteDifferences) {
    NeeNetwork net(5, 3);
    const float x[kNeeInputs] = {0.3f, -0.2f, 0.7f, 0.0f, 1.0f, 0.0f, 0.5f, -0.5f, 0.7071f};
    const float target[5] = {0.1f, -0.4f, 0.3f, 0.2f, 0.0f};  // loss = sum_o target_o * logit_o
    std::vector<float> grad(net.parameters().size(), 0.0f);
    NeeNetwork::Activations a;
    net.forward(x, a);
    float dLogits[LightSampler::kMaxLightGroups] = {};
    for (int o = 0; o < 5; ++o) dLogits[o] = target[o];
    net.backward(x, a, dLogits, grad.data());
    auto loss = [&]() {
        NeeNetwork::Activations b;
        net.forward(x, b);
        double s = 0.0;
        for (int o = 0; o < 5; ++o) s += double(target[o]) * b.logits[o];
        return s;
    };
    SplitMix64 rng(11);
    int compared = 0;
    for (int k = 0; k < 300; ++k) {
        size_t i = size_t(rng.below(net.parameters().size()));
        float keep = net.parameters()[i];
        const float h = 1e-2f;
        net.parameters()[i] = keep + h;
        double up = loss();
        net.parameters()[i] = keep - h;
        double down = loss();
        net.parameters()[i] = keep;
        double numeric = (up - down) / (2.0 * h);
        EXPECT_NEAR(grad[i], numeric, 2e-3 + 2e-2 * std::abs(numeric)) << "parameter " << i;
        compared += grad[i] != 0.0f;
    }
    EXPECT_GT(compared, 50);
}

// Closed form: point-to-rectangle form factor for a point under a corner of a parallel a x b rectangle at
// height h (X = a / h, Y = b / h).
double cornerFormFactor(double X, double Y) {
    const double pi = 3.14159265358979323846;
    double sx = std::sqrt(1.0 + X * X), sy = std::sqrt(1.0 + Y * Y);
    return (X / sx * std::atan(Y / sx) + Y / sy * std::atan(X / sy)) / (2.0 * pi);
}

TEST(QuadLights, IrradianceUnderAQuadLightMatchesTheFormFactor) {
    // A 2 x 1 one-sided quad light of radiance Le at height h over the centre of a Lambertian plane of
    // albedo a: the plane's radiance there is a Le F, F the form factor (four corner rectangles of 1 x 0.5).
    // Checked through the power sampler (one triangle, then a point in it) and through the light groups
    // (uniform selection: the quad sampled as one parallelogram), direct light only.
    const float a = 0.5f, h = 1.0f, Le = 3.0f;
    Scene scene = test::makeLitPlane(a);
    scene.cameras[0].xmag = scene.cameras[0].ymag = 0.01f;  // a tiny patch under the light's centre,
    scene.cameras[0].position.z = 0.5f;                      // seen from below the light
    Material light;
    light.baseColor = glm::vec3(0.0f);
    light.emission = glm::vec3(Le);
    scene.materials.push_back(light);
    TriangleMesh& mesh = scene.mesh;
    uint32_t base = uint32_t(mesh.positions.size());
    for (glm::vec2 c : {glm::vec2(-1, -0.5f), glm::vec2(1, -0.5f), glm::vec2(1, 0.5f), glm::vec2(-1, 0.5f)}) {
        mesh.positions.emplace_back(c.x, c.y, h);
        mesh.normals.emplace_back(0, 0, -1);
        mesh.uv0.emplace_back(0.0f);
        mesh.uv1.emplace_back(0.0f);
    }
    mesh.triangles.push_back({base, base + 2, base + 1});  // wound so that the light faces -z
    mesh.triangles.push_back({base, base + 3, base + 2});
    mesh.materialIds.push_back(1);
    mesh.materialIds.push_back(1);
    scene.updateBounds();
    const double expected = a * Le * 4.0 * cornerFormFactor(1.0 / h, 0.5 / h);

    Accel accel(scene);
    LightSampler lights(scene);
    ASSERT_EQ(lights.groupCount(), 1u);
    EXPECT_TRUE(lights.groupIsParallelogram(0));
    RenderSettings s;
    s.width = s.height = 4;
    s.spp = 1024;
    s.maxDepth = 2;
    for (NeeMode mode : {NeeMode::Power, NeeMode::Uniform}) {
        NeeSettings ns;
        ns.mode = mode;
        LightSelector selector(lights, scene.bounds, ns);
        PathTracer tracer(scene, accel, lights, &selector);
        Image image = tracer.render(scene.cameras[0], s);
        EXPECT_NEAR(image.mean().x, expected, 2e-3 * expected) << neeModeName(mode);
    }
}

struct Rig {
    Scene scene;
    Accel accel;
    LightSampler lights;
    Camera camera;
    explicit Rig(Scene s)
        : scene(std::move(s)), accel(scene.mesh), lights(scene),
          camera(scene.cameras.empty() ? frameBounds(scene.bounds) : scene.cameras[0]) {}
};

OnlineRenderResult renderWith(const Rig& rig, NeeMode mode, const RenderSettings& s, LightSelector** keep = nullptr,
                              uint32_t netSeed = 0, uint32_t warmupSteps = NeeSettings{}.warmupSteps) {
    NeeSettings ns;
    ns.mode = mode;
    ns.seed = netSeed;
    ns.warmupSteps = warmupSteps;
    static thread_local std::unique_ptr<LightSelector> last;
    last = std::make_unique<LightSelector>(rig.lights, rig.scene.bounds, ns);
    PathTracer tracer(rig.scene, rig.accel, rig.lights, last.get());
    OnlineRenderResult r = renderOnline(tracer, last.get(), rig.camera, s);
    if (keep) *keep = last.get();
    return r;
}

TEST(LearnedNee, MeanOfLearnedRendersMatchesUniformReference) {
    // Unbiasedness: independent learned renders (own seeds and networks) against a uniform-selection
    // reference, for both variants: 12 trained while rendering (the paper's: the distribution changes
    // between a pixel's samples) and 12 after a short warm-up. Paths of up to 3 segments so that the MIS
    // weight at the second vertex uses the learned probabilities of the first.
    Rig rig(splitRooms());
    RenderSettings s;
    s.width = s.height = 24;
    s.maxDepth = 3;
    s.spp = 16;
    RenderSettings ref = s;
    ref.spp = 2048;
    ref.seed = 7;
    OnlineRenderResult u = renderWith(rig, NeeMode::Uniform, ref);
    const double mu = u.image.mean().x + u.image.mean().y + u.image.mean().z;
    for (uint32_t warmup : {0u, 64u}) {
        std::vector<double> means;
        for (uint32_t k = 0; k < 12; ++k) {
            s.seed = 100 + k;
            OnlineRenderResult r = renderWith(rig, NeeMode::Learned, s, nullptr, k, warmup);
            EXPECT_GT(r.stats.trainingSteps, 0u);
            EXPECT_EQ(r.stats.warmupPaths > 0, warmup > 0);
            means.push_back(r.image.mean().x + r.image.mean().y + r.image.mean().z);
        }
        double m = 0.0, v = 0.0;
        for (double x : means) m += x;
        m /= double(means.size());
        for (double x : means) v += (x - m) * (x - m);
        double se = std::sqrt(v / double(means.size() - 1) / double(means.size()));
        EXPECT_GT(se, 0.0);
        EXPECT_NEAR(m, mu, 4.0 * se + 0.002 * mu) << "warm-up " << warmup << ", standard error " << se;
        EXPECT_LT(se, 0.02 * mu);  // the check has teeth: a 5% bias would fail it
    }
}

TEST(LearnedNee, AfterTheWarmUpTheImageIsTheTileRenderersWithTheFrozenNetwork) {
    // The warm-up leaves the network frozen, and the image is rendered with it alone: the tile renderer with
    // the same (frozen) selector gives the same image, byte for byte. The warm-up really trained it: the
    // weights differ from a fresh network's.
    Rig rig(splitRooms());
    RenderSettings s;
    s.width = s.height = 24;
    s.maxDepth = 3;
    s.spp = 4;
    s.seed = 11;
    NeeSettings ns;
    ns.mode = NeeMode::Learned;
    ns.warmupSteps = 32;
    LightSelector selector(rig.lights, rig.scene.bounds, ns);
    const std::vector<float> initial = selector.network().parameters();
    PathTracer tracer(rig.scene, rig.accel, rig.lights, &selector);
    OnlineRenderResult r = renderOnline(tracer, &selector, rig.camera, s);
    EXPECT_FALSE(selector.settings().train);
    // Exactly 32 steps, in rounds of 1-16 mini-batches of 64 paths with 1 or 2 steps each (2 when a round
    // recorded more than 64 contributions).
    EXPECT_EQ(r.stats.trainingSteps, 32u);
    EXPECT_GE(r.stats.rounds, 16u);
    EXPECT_LE(r.stats.rounds, 32u);
    EXPECT_EQ(r.stats.warmupPaths % 64, 0u);
    EXPECT_GE(r.stats.warmupPaths, r.stats.rounds * 64u);
    EXPECT_LE(r.stats.warmupPaths, r.stats.rounds * 16u * 64u);
    EXPECT_NE(0, std::memcmp(initial.data(), selector.network().parameters().data(), initial.size() * sizeof(float)));
    const std::vector<float> frozen = selector.network().parameters();
    Image tiles = tracer.render(rig.camera, s);
    EXPECT_EQ(0, std::memcmp(r.image.pixels.data(), tiles.pixels.data(), tiles.pixels.size() * sizeof(glm::vec3)));
    EXPECT_EQ(0, std::memcmp(frozen.data(), selector.network().parameters().data(), frozen.size() * sizeof(float)));
}

TEST(LearnedNee, NoWarmUpWhereThereIsNothingToLearn) {
    RenderSettings s;
    s.width = s.height = 16;
    s.spp = 2;
    {
        // One light (the Cornell box): the network would never be evaluated, so no warm-up.
        Rig rig(loadGltf(test::sourcePath("scenes/cornell-box/cornell-box.gltf")));
        ASSERT_EQ(rig.lights.groupCount(), 1u);
        OnlineRenderResult r = renderWith(rig, NeeMode::Learned, s);
        EXPECT_EQ(r.stats.warmupPaths, 0u);
        EXPECT_EQ(r.stats.trainingSteps, 0u);
        EXPECT_GT(r.image.mean().x, 0.0f);
    }
    {
        // Eight lights, but the camera looks away from the rooms: nothing is ever recorded, and the warm-up
        // gives up after 8 empty rounds of 16 mini-batches instead of tracing its full budget.
        Rig rig(splitRooms());
        rig.camera.worldFromCamera = glm::mat3(-1.0f) * rig.camera.worldFromCamera;  // turned around
        rig.camera.worldFromCamera[1] = -rig.camera.worldFromCamera[1];  // keep it right-handed
        OnlineRenderResult r = renderWith(rig, NeeMode::Learned, s);
        EXPECT_EQ(r.stats.trainingSteps, 0u);
        EXPECT_EQ(r.stats.rounds, 8u);
        // The first round assumes one record per path (2 mini-batches for two steps), the empty ones 16.
        EXPECT_EQ(r.stats.warmupPaths, uint64_t(2 * 64 + 7 * 16 * 64));
    }
}

// Group indices of the two lights of room r (lintel, pilaster): the lights primitive lists them room by room.
TEST(LearnedNee, LearnsTheVisibleLightsOfEachRoom) {
    Rig rig(splitRooms());
    RenderSettings s;
    s.width = s.height = 64;
    s.spp = 32;
    LightSelector* selector = nullptr;
    OnlineRenderResult r = renderWith(rig, NeeMode::Learned, s, &selector);
    ASSERT_NE(selector, nullptr);
    // Points on the floor, back wall and side walls of every room, looked at from the opening.
    const float room = 1.0f, wall = 0.04f;
    SplitMix64 rng(3);
    for (int iy = 0; iy < 2; ++iy)
        for (int ix = 0; ix < 2; ++ix) {
            int roomIndex = iy * 2 + ix;
            float x0 = ix ? room + wall : 0.0f, y0 = iy ? room + wall : 0.0f;
            double mass = 0.0;
            int n = 0;
            for (int k = 0; k < 200; ++k) {
                glm::vec3 p, nrm;
                float u = 0.05f + 0.9f * rng.uniform(), w = 0.1f + 0.8f * rng.uniform();
                switch (k % 3) {
                    case 0: p = {x0 + u, y0 + 0.0005f, -w}; nrm = {0, 1, 0}; break;  // floor
                    case 1: p = {x0 + u, y0 + w, -0.9995f}; nrm = {0, 0, 1}; break;  // back wall
                    default: p = {x0 + 0.0005f, y0 + u, -w}; nrm = {1, 0, 0}; break;  // left wall
                }
                glm::vec3 eye = rig.camera.position;
                glm::vec3 wo = glm::normalize(eye - p);
                if (glm::dot(wo, nrm) <= 0.0f) wo = nrm;
                float probs[LightSampler::kMaxLightGroups];
                // The network's own distribution over the candidates (before the uniform share and the
                // rounding to units of 1/64, which alone give six hidden lights 6/64).
                selector->networkDistribution(p, nrm, wo, selector->candidates(p, nrm), probs);
                // What is sampled: whole units of 1/64, at least one per candidate, adding up to one.
                float used[LightSampler::kMaxLightGroups];
                ASSERT_TRUE(selector->distribution(LightSampleContext{p, nrm, nrm, wo, 0}, used, nullptr));
                uint64_t cand = selector->candidates(p, nrm);
                int unitSum = 0;
                for (size_t g = 0; g < rig.lights.groupCount(); ++g) {
                    float units = used[g] * 64.0f;
                    ASSERT_EQ(units, std::round(units));
                    ASSERT_EQ(units >= 1.0f, bool(cand >> g & 1u));
                    unitSum += int(units);
                }
                ASSERT_EQ(unitSum, 64);
                mass += probs[2 * roomIndex] + probs[2 * roomIndex + 1];
                ++n;
            }
            double share = mass / n;
            EXPECT_GE(share, 0.9) << "room " << roomIndex;
            std::printf("room %d: %.3f of the selection probability on its own two lights\n", roomIndex, share);
        }
    EXPECT_GT(r.stats.trainingSteps, 0u);
}

TEST(LearnedNee, ByteIdenticalForOneAndTwoThreads) {
    Rig rig(splitRooms());
    RenderSettings s;
    s.width = s.height = 32;
    s.spp = 4;
    s.seed = 9;
    OnlineRenderResult one, two;
    std::vector<float> w1, w2;
    LightSelector* sel = nullptr;
    {
        ThreadScope threads(1);
        one = renderWith(rig, NeeMode::Learned, s, &sel);
        w1 = sel->network().parameters();
    }
    {
        ThreadScope threads(2);
        two = renderWith(rig, NeeMode::Learned, s, &sel);
        w2 = sel->network().parameters();
    }
    ASSERT_EQ(one.image.pixels.size(), two.image.pixels.size());
    EXPECT_EQ(0, std::memcmp(one.image.pixels.data(), two.image.pixels.data(), one.image.pixels.size() * sizeof(glm::vec3)));
    ASSERT_EQ(w1.size(), w2.size());
    EXPECT_EQ(0, std::memcmp(w1.data(), w2.data(), w1.size() * sizeof(float)));
    EXPECT_EQ(one.firstLight, two.firstLight);
    EXPECT_GT(one.stats.trainingSteps, 0u);
}

TEST(LearnedNee, UniformThroughRoundsEqualsTheTileRenderer) {
    // Same sampler per (pixel, sample): the round-based renderer gives the tile renderer's image exactly.
    Rig rig(splitRooms());
    RenderSettings s;
    s.width = s.height = 24;
    s.spp = 4;
    s.seed = 5;
    NeeSettings ns;
    ns.mode = NeeMode::Uniform;
    LightSelector selector(rig.lights, rig.scene.bounds, ns);
    PathTracer tracer(rig.scene, rig.accel, rig.lights, &selector);
    OnlineRenderResult r = renderOnline(tracer, &selector, rig.camera, s);
    Image tiles = tracer.render(rig.camera, s);
    EXPECT_EQ(0, std::memcmp(r.image.pixels.data(), tiles.pixels.data(), tiles.pixels.size() * sizeof(glm::vec3)));
}

}  // namespace
}  // namespace nrad
