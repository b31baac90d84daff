// The BSDF's lanes (bsdf_lanes.h) against Bsdf one vertex at a time: the same bits for eval and pdf at a light
// direction and for the sample, over random and edge-case vertices (wo below the shading plane, light
// directions below and in it, roughness 0, pure metal, no specular layer, the disk mapping's centre and axes,
// lobe choices at the probability's edge). Built twice: in bsdf_tests with the instruction-set clones this
// machine picks, in bsdf_lanes_plain_tests with the default alone.
#include "baker/render/bsdf_lanes.h"

#include <cstring>
#include <random>
#include <vector>

#include <gtest/gtest.h>

#include "support/lane_checks.h"

#include "baker/render/bsdf.h"

namespace nrad {
namespace {

using test::randomDirection;
using test::sameBits;

TEST(BsdfLanes, AreTheBsdfBitForBit) {
    std::mt19937 rng(11);
    std::uniform_real_distribution<float> u01(0.0f, 1.0f);
    const float edgeU[] = {0.0f, 0.5f, 0.25f, 0.75f, 0.999f};
    BsdfLanes lanes;
    size_t checked = 0, specularSamples = 0, diffuseSamples = 0, invalid = 0;
    for (int round = 0; round < 400; ++round) {
        const size_t n = 1 + size_t(round) % BsdfLanes::kLanes;
        std::vector<BsdfParams> params(n);
        std::vector<glm::vec3> normal(n), wo(n), wi(n);
        for (size_t k = 0; k < n; ++k) {
            BsdfParams& p = params[k];
            p.baseColor = glm::vec3(u01(rng), u01(rng), u01(rng));
            const int kind = int(rng() % 6);
            p.metallic = kind == 0 ? 1.0f : (kind == 1 ? u01(rng) : 0.0f);
            p.roughness = kind == 2 ? 0.0f : u01(rng);
            p.specular = kind == 3 ? 0.0f : u01(rng);
            p.specularColor = glm::vec3(u01(rng), u01(rng), u01(rng)) * 1.5f;
            p.ior = 1.0f + 1.5f * u01(rng);
            normal[k] = randomDirection(rng);
            if (k % 7 == 3) normal[k] = glm::vec3(0.0f, 0.0f, -1.0f);
            wo[k] = randomDirection(rng);
            if (glm::dot(wo[k], normal[k]) < 0.0f && k % 5 != 0) wo[k] = -wo[k];  // a fifth may lie below
            if (k % 13 == 6) wo[k] = normal[k];  // straight on: the visible-normal frame's degenerate case
            wi[k] = randomDirection(rng);
            if (k % 11 == 5) wi[k] = glm::normalize(glm::cross(normal[k], wo[k]));  // in the plane, about
            lanes.nx[k] = normal[k].x, lanes.ny[k] = normal[k].y, lanes.nz[k] = normal[k].z;
            lanes.wox[k] = wo[k].x, lanes.woy[k] = wo[k].y, lanes.woz[k] = wo[k].z;
            lanes.lx[k] = wi[k].x, lanes.ly[k] = wi[k].y, lanes.lz[k] = wi[k].z;
            lanes.baseR[k] = p.baseColor.x, lanes.baseG[k] = p.baseColor.y, lanes.baseB[k] = p.baseColor.z;
            lanes.metallic[k] = p.metallic, lanes.roughness[k] = p.roughness, lanes.specular[k] = p.specular;
            lanes.specR[k] = p.specularColor.x, lanes.specG[k] = p.specularColor.y, lanes.specB[k] = p.specularColor.z;
            lanes.ior[k] = p.ior;
            lanes.uLobe[k] = u01(rng);
            if (k % 9 == 4) lanes.uLobe[k] = Bsdf(Frame::fromNormal(normal[k]), p).outgoing(wo[k]).pSpec;  // the lobes' edge
            lanes.u0[k] = k % 4 == 1 ? edgeU[rng() % 5] : u01(rng);
            lanes.u1[k] = k % 4 == 2 ? edgeU[rng() % 5] : u01(rng);
        }
        shadeLanes(lanes, n);
        for (size_t k = 0; k < n; ++k) {
            const Bsdf bsdf(Frame::fromNormal(normal[k]), params[k]);
            const Bsdf::Outgoing out = bsdf.outgoing(wo[k]);
            const glm::vec3 f = bsdf.eval(out, wi[k]);
            const float pdf = bsdf.pdf(out, wi[k]);
            ASSERT_TRUE(sameBits(lanes.evalR[k], f.x) && sameBits(lanes.evalG[k], f.y) && sameBits(lanes.evalB[k], f.z))
                << "round " << round << ", lane " << k << ": eval " << lanes.evalR[k] << " against " << f.x;
            ASSERT_TRUE(sameBits(lanes.evalPdf[k], pdf)) << "round " << round << ", lane " << k;
            const BsdfSample s = bsdf.sample(out, lanes.uLobe[k], glm::vec2(lanes.u0[k], lanes.u1[k]));
            ASSERT_TRUE(sameBits(lanes.samplePdf[k], s.pdf)) << "round " << round << ", lane " << k << ": pdf "
                                                             << lanes.samplePdf[k] << " against " << s.pdf;
            ASSERT_TRUE(sameBits(lanes.sampleX[k], s.wi.x) && sameBits(lanes.sampleY[k], s.wi.y) && sameBits(lanes.sampleZ[k], s.wi.z))
                << "round " << round << ", lane " << k;
            ASSERT_TRUE(sameBits(lanes.sampleR[k], s.f.x) && sameBits(lanes.sampleG[k], s.f.y) && sameBits(lanes.sampleB[k], s.f.z))
                << "round " << round << ", lane " << k;
            ++checked;
            if (!s.valid()) ++invalid;
            else if (lanes.uLobe[k] < out.pSpec) ++specularSamples;
            else ++diffuseSamples;
        }
    }
    // Every branch was taken often.
    EXPECT_GT(checked, 10000u);
    EXPECT_GT(specularSamples, 1000u);
    EXPECT_GT(diffuseSamples, 1000u);
    EXPECT_GT(invalid, 500u);
}

}  // namespace
}  // namespace nrad
