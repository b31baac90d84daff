// Scattering in lanes (scatter_lanes.h) against the scalar code it reorganises: LightSampler::sample, the
// candidate test, the Bsdf at the light direction and its sample, shadowRay, the power heuristic, the
// throughput and Russian roulette of PathTracer::scatterEnd, the same bits in every output. Quad lights (one-sided: a two-sided pair of triangles
// is no parallelogram group) level, tilted, far from the origin and tiny; vertices in front of, behind and in
// the plane of the light, at its corner, lit from below their geometric surface, black and glossy materials. Built twice: in render_tests with the
// instruction-set clones this machine picks, in scatter_lanes_plain_tests with the default alone.
#include "baker/render/scatter_lanes.h"

#include <cstring>
#include <limits>
#include <random>
#include <vector>

#include <gtest/gtest.h>

#include "support/lane_checks.h"

#include "baker/lights/light_sampler.h"
#include "baker/render/bsdf.h"
#include "baker/render/path_tracer.h"
#include "baker/render/surface.h"

namespace nrad {
namespace {

using test::randomDirection;
using test::sameBits;

// One quad light (corner c, edges e1 and e2; its triangles (c, c+e1, c+e1+e2) and (c, c+e1+e2, c+e2)).
Scene quadLightScene(const glm::vec3& c, const glm::vec3& e1, const glm::vec3& e2) {
    Scene scene;
    scene.sourcePath = "<quad light>";
    Material m;
    m.emission = glm::vec3(4.0f, 2.0f, 0.5f);
    scene.materials.push_back(m);
    TriangleMesh& mesh = scene.mesh;
    const glm::vec3 n = glm::normalize(glm::cross(e1, e2));
    for (const glm::vec3& p : {c, c + e1, c + e1 + e2, c + e2}) {
        mesh.positions.push_back(p);
        mesh.normals.push_back(n);
        mesh.uv0.emplace_back(0.0f);
        mesh.uv1.emplace_back(0.0f);
    }
    mesh.triangles = {{0, 1, 2}, {0, 2, 3}};
    mesh.materialIds = {0, 0};
    scene.updateBounds();
    return scene;
}

float powerHeuristic(float f, float g) {  // path_tracer.cpp's
    float f2 = f * f, g2 = g * g;
    if (std::isinf(f2)) return 1.0f;
    return f2 + g2 > 0.0f ? f2 / (f2 + g2) : 0.0f;
}

bool isBlack(const glm::vec3& v) { return v.x <= 0.0f && v.y <= 0.0f && v.z <= 0.0f; }

TEST(ScatterLanes, AreTheScalarCodeBitForBit) {
    struct Light {
        glm::vec3 c, e1, e2;
        float reach;  // how far from the light the vertices lie
    };
    const Light lightCases[] = {
        {{-0.5f, 1.9f, -0.5f}, {1.0f, 0.0f, 0.0f}, {0.0f, 0.0f, 1.0f}, 2.0f},  // a ceiling panel facing down
        {{0.2f, -0.3f, 0.1f}, {0.7f, 0.2f, -0.1f}, {0.1f, 0.4f, 0.9f}, 1.5f},  // tilted
        {{1.0e4f, 2.0e4f, -3.0e4f}, {3.0f, 0.0f, 1.0f}, {0.0f, 2.0f, 0.0f}, 50.0f},  // far from the origin
        {{0.0f, 0.0f, 0.0f}, {1e-3f, 0.0f, 0.0f}, {0.0f, 1e-3f, 0.0f}, 1e-2f},  // tiny, near the origin
    };
    std::mt19937 rng(5);
    std::uniform_real_distribution<float> u01(0.0f, 1.0f), s11(-1.0f, 1.0f);
    ScatterLanes lanes;
    size_t checked = 0, pending = 0, notPending = 0, more = 0, ended = 0, rouletteEnded = 0;
    for (const Light& lc : lightCases) {
        const Scene scene = quadLightScene(lc.c, lc.e1, lc.e2);
        const LightSampler lights(scene);
        ASSERT_TRUE(lights.groupIsParallelogram(0)) << "light " << (&lc - lightCases);
        const glm::vec3 centre = lc.c + 0.5f * (lc.e1 + lc.e2);
        for (int round = 0; round < 200; ++round) {
            const size_t n = 1 + size_t(round) % ScatterLanes::kLanes;
            lanes.rouletteThreshold = round % 2 == 0 ? 1.0f : 0.25f;
            std::vector<SurfaceInteraction> si(n);
            std::vector<glm::vec2> u(n);
            std::vector<glm::vec3> beta(n);
            for (size_t k = 0; k < n; ++k) {
                SurfaceInteraction& v = si[k];
                v.p = centre + lc.reach * glm::vec3(s11(rng), s11(rng), s11(rng));
                if (k % 17 == 3) v.p = lc.c + u01(rng) * lc.e1 + u01(rng) * lc.e2;  // in the light's plane
                if (k % 19 == 7) v.p = lc.c;  // at the light's corner: the sample may be the point itself
                v.ng = randomDirection(rng);
                v.ns = glm::normalize(v.ng + 0.3f * randomDirection(rng));
                v.wo = randomDirection(rng);
                if (glm::dot(v.wo, v.ng) < 0.0f) v.wo = -v.wo;
                if (glm::dot(v.ns, v.wo) <= 0.0f) v.ns = v.ng;
                v.margin = rayOffset(v.p) * (k % 3 == 0 ? 8.0f : 1.0f);
                BsdfParams& b = v.bsdf;
                b.baseColor = k % 23 == 5 ? glm::vec3(0.0f) : glm::vec3(u01(rng), u01(rng), u01(rng));
                b.metallic = k % 4 == 0 ? 1.0f : 0.0f;
                b.roughness = k % 5 == 0 ? 0.0f : u01(rng);
                b.specular = k % 23 == 5 ? 0.0f : u01(rng);
                b.specularColor = glm::vec3(u01(rng), u01(rng), u01(rng));
                b.ior = 1.0f + u01(rng);
                u[k] = glm::vec2(u01(rng), u01(rng));
                if (k % 13 == 2) u[k] = glm::vec2(0.0f, 0.0f);
                if (k % 13 == 9) u[k] = glm::vec2(0.5f, 0.5f);  // on the quad's diagonal
                beta[k] = glm::vec3(u01(rng), u01(rng), u01(rng)) * 2.0f;
                lanes.uRoulette[k] = u01(rng);
                lanes.roulette[k] = k % 3 == 1 ? 0.0f : 1.0f;
                LightSampler::QuadPick q;
                ASSERT_TRUE(lights.pickQuad(u[k], q));
                lanes.px[k] = v.p.x, lanes.py[k] = v.p.y, lanes.pz[k] = v.p.z;
                lanes.ngx[k] = v.ng.x, lanes.ngy[k] = v.ng.y, lanes.ngz[k] = v.ng.z;
                lanes.margin[k] = v.margin;
                lanes.betaR[k] = beta[k].x, lanes.betaG[k] = beta[k].y, lanes.betaB[k] = beta[k].z;
                lanes.plx[k] = q.point.x, lanes.ply[k] = q.point.y, lanes.plz[k] = q.point.z;
                lanes.lnx[k] = q.normal.x, lanes.lny[k] = q.normal.y, lanes.lnz[k] = q.normal.z;
                lanes.frontR[k] = q.front.x, lanes.frontG[k] = q.front.y, lanes.frontB[k] = q.front.z;
                lanes.backR[k] = q.back.x, lanes.backG[k] = q.back.y, lanes.backB[k] = q.back.z;
                lanes.area[k] = q.area, lanes.lightMargin[k] = q.margin, lanes.pick[k] = q.pick;
                BsdfLanes& B = lanes.bsdf;
                B.nx[k] = v.ns.x, B.ny[k] = v.ns.y, B.nz[k] = v.ns.z;
                B.wox[k] = v.wo.x, B.woy[k] = v.wo.y, B.woz[k] = v.wo.z;
                B.baseR[k] = b.baseColor.x, B.baseG[k] = b.baseColor.y, B.baseB[k] = b.baseColor.z;
                B.metallic[k] = b.metallic, B.roughness[k] = b.roughness, B.specular[k] = b.specular;
                B.specR[k] = b.specularColor.x, B.specG[k] = b.specularColor.y, B.specB[k] = b.specularColor.z;
                B.ior[k] = b.ior;
                B.uLobe[k] = u01(rng), B.u0[k] = u01(rng), B.u1[k] = u01(rng);
            }
            scatterLanes(lanes, n);
            for (size_t k = 0; k < n; ++k) {
                const SurfaceInteraction& v = si[k];
                const LightSample ls = lights.sample(v.p, u[k]);
                const bool candidate = ls.pdf > 0.0f && !isBlack(ls.Li) && glm::dot(ls.wi, v.ng) > 0.0f;
                const Bsdf bsdf(Frame::fromNormal(v.ns), v.bsdf);
                const Bsdf::Outgoing out = bsdf.outgoing(v.wo);
                const BsdfSample bs = bsdf.sample(out, lanes.bsdf.uLobe[k], glm::vec2(lanes.bsdf.u0[k], lanes.bsdf.u1[k]));
                ASSERT_TRUE(sameBits(lanes.bsdf.samplePdf[k], bs.pdf) && sameBits(lanes.bsdf.sampleX[k], bs.wi.x) &&
                            sameBits(lanes.bsdf.sampleG[k], bs.f.y))
                    << "light " << (&lc - lightCases) << ", round " << round << ", lane " << k;
                glm::vec3 f(0.0f);
                float bsdfPdf = 0.0f;
                if (candidate) {
                    f = bsdf.eval(out, ls.wi) * std::abs(glm::dot(ls.wi, v.ns));
                    bsdfPdf = bsdf.pdf(out, ls.wi);
                }
                // extend()
                bool goesOn = bs.valid() && glm::dot(bs.wi, v.ng) > 0.0f, byRoulette = false;
                glm::vec3 newBeta = beta[k];
                if (goesOn) {
                    newBeta *= bs.f * (std::abs(glm::dot(bs.wi, v.ns)) / bs.pdf);
                    goesOn = !isBlack(newBeta) && std::isfinite(newBeta.x) && std::isfinite(newBeta.y) && std::isfinite(newBeta.z);
                }
                if (goesOn && lanes.roulette[k] > 0.0f) {
                    const float q = std::min(1.0f, std::max(newBeta.x, std::max(newBeta.y, newBeta.z)) / lanes.rouletteThreshold);
                    if (lanes.uRoulette[k] >= q)
                        goesOn = false, byRoulette = true;
                    else
                        newBeta /= q;
                }
                ASSERT_EQ(lanes.more[k] > 0.0f, goesOn) << "light " << (&lc - lightCases) << ", round " << round << ", lane " << k;
                if (goesOn) {
                    ++more;
                    ASSERT_TRUE(sameBits(lanes.betaR[k], newBeta.x) && sameBits(lanes.betaG[k], newBeta.y) &&
                                sameBits(lanes.betaB[k], newBeta.z) && sameBits(lanes.extensionTnear[k], v.spawnDistance(bs.wi)))
                        << "light " << (&lc - lightCases) << ", round " << round << ", lane " << k;
                } else {
                    ++ended;
                    rouletteEnded += byRoulette;
                }
                const bool expectPending = candidate && !isBlack(f);
                ASSERT_EQ(lanes.pending[k] > 0.0f, expectPending) << "light " << (&lc - lightCases) << ", round " << round << ", lane " << k;
                ++checked;
                if (!expectPending) {
                    ++notPending;
                    continue;
                }
                ++pending;
                glm::vec3 o, d;
                float tnear, tfar;
                shadowRay(v, ls, o, d, tnear, tfar);
                const glm::vec3 contribution = beta[k] * f * ls.Li * (powerHeuristic(ls.pdf, bsdfPdf) / ls.pdf);
                ASSERT_TRUE(sameBits(lanes.wix[k], d.x) && sameBits(lanes.wiy[k], d.y) && sameBits(lanes.wiz[k], d.z))
                    << "light " << (&lc - lightCases) << ", round " << round << ", lane " << k;
                ASSERT_TRUE(sameBits(lanes.tnear[k], tnear) && sameBits(lanes.tfar[k], tfar))
                    << "light " << (&lc - lightCases) << ", round " << round << ", lane " << k << ": " << lanes.tnear[k]
                    << " " << lanes.tfar[k] << " against " << tnear << " " << tfar;
                ASSERT_TRUE(sameBits(lanes.contribR[k], contribution.x) && sameBits(lanes.contribG[k], contribution.y) &&
                            sameBits(lanes.contribB[k], contribution.z))
                    << "light " << (&lc - lightCases) << ", round " << round << ", lane " << k << ": " << lanes.contribR[k]
                    << " against " << contribution.x;
            }
        }
    }
    // Every outcome, many times each.
    EXPECT_GT(pending, checked / 5);
    EXPECT_GT(notPending, checked / 5);
    EXPECT_GT(more, checked / 5);
    EXPECT_GT(ended, checked / 10);
    EXPECT_GT(rouletteEnded, checked / 50);
}

}  // namespace
}  // namespace nrad
