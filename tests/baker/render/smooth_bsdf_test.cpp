// Smooth and near-mirror surfaces under a uniform white sky (issue 37, item 4): the directional albedo that the
// path tracer's BSDF sampling estimates (Bsdf::outgoing, sample, and the path's weight f |wi.n| / pdf, the very
// calls and arithmetic of PathTracer::extend) and the integrals of eval and pdf over the lobe (what next event
// estimation and multiple importance sampling use) against the model's exact value, integrated in double
// precision, and against the closed form of a perfectly smooth surface (Schlick's Fresnel and its hemispherical
// average), for roughness 0 to 0.1 (alpha clamped at 1e-3) and view angles 0 to 85 degrees.
//
// Why the expected numbers are what they are. For the GGX lobe with height-correlated Smith masking,
// f cos = F(wo.h) D(h) G2 / (4 wo.z), and with dwi = 4 (wo.h) dwh and D(h) dwh = P22(s) ds / cos(theta_h) in
// slope space (s the microfacet's slope, h = (-sx, -sy, 1) / sqrt(1 + |s|^2)), the reflected energy is
//     E = 1 / wo.z  integral F(wo.h) G2(wo, wi) max(0, wo.z - s.wo_xy) [wi.z > 0] P22(s) ds,
// and GGX's P22 ds is du dphi / (2 pi) for |s| = alpha sqrt(u / (1 - u)): a smooth integrand over the unit
// square, integrated by the midpoint rule (with u = 1 - (1 - v)^2, so that the slopes' heavy tail is sampled
// evenly). Schlick's F = F0 + (1 - F0) S with S = (1 - wo.h)^5 is linear in F0, so two integrals per view angle
// and alpha, A (of G2) and B (of S G2), give every material's lobe: a metal reflects F0 A + (1 - F0) B, a
// dielectric's specular layer the same with its F0, a thin sheet transmits base (A - that) through its
// mirrored lobe, and the Lambertian base of an opaque dielectric (weighted by (1 - F(n.wo)) (1 - F(n.wi)),
// docs/rendering.md) adds base (1 - F(cos theta_o)) (1 - F0 - (1 - F0) / 21), since the hemispherical cosine
// average of (1 - mu)^5 is 2 integral (1 - mu)^5 mu dmu = 1 / 21. As alpha -> 0, s -> 0: A -> 1 and
// B -> (1 - cos theta_o)^5, so a smooth metal reflects exactly Schlick's F(cos theta_o) and a clear sheet passes
// all that it does not reflect (the closed form; Cycles' and every renderer's mirror). Up to roughness 0.05 at
// every angle, and at 0.1 up to 70 degrees, the model is that closed form within 0.3%. At roughness 0.1 seen at
// 80 and 85 degrees it is not, and should not be: a single-scattering microfacet model (glTF's, without
// multiple-scattering compensation) loses what its microfacets shadow (G2 / G1: 0.46% at 85 degrees) and what
// the lobe's tail reflects below the horizon (0.32%), so a white mirror reflects 0.9981 / 0.9922, and Schlick's
// Fresnel averaged over the visible microfacets is below the macro normal's (a clear coat: 0.6332 against
// 0.6484 at 85 degrees). There the estimate is held to the model's exact value, and to at most the closed form.
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <random>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "baker/render/bsdf.h"
#include "baker/util/threads.h"
#include "support/test_scenes.h"

namespace nrad {
namespace {

constexpr double kPi = 3.14159265358979323846;
const float kRoughness[] = {0.0f, 0.001f, 0.01f, 0.05f, 0.1f};
const double kViewDegrees[] = {0.0, 15.0, 30.0, 45.0, 60.0, 70.0, 80.0, 85.0};

// A shading normal off the axes, so that the frame's rounding is that of a real vertex (not the identity).
const glm::dvec3 kNormal = glm::normalize(glm::dvec3(0.31, -0.23, 0.92));

struct LocalFrame {
    glm::dvec3 s, t, n;
    glm::dvec3 toWorld(const glm::dvec3& v) const { return s * v.x + t * v.y + n * v.z; }
};
LocalFrame localFrame() {
    const glm::dvec3 n = kNormal;
    const glm::dvec3 s = glm::normalize(glm::cross(glm::abs(n.x) < 0.9 ? glm::dvec3(1, 0, 0) : glm::dvec3(0, 1, 0), n));
    return {s, glm::cross(n, s), n};
}

double lambda(double c, double alpha) {
    const double c2 = c * c;
    return 0.5 * (std::sqrt(1.0 + alpha * alpha * (1.0 - c2) / c2) - 1.0);
}

// The model's lobe integrals in double precision (see the top of the file): A = integral of G2, B = of
// (1 - wo.h)^5 G2, P = of G1 (the pdf's integral over the reflected directions above the horizon), each weighted
// by the visible-normal measure max(0, wo.z - s.wo_xy) / wo.z P22 ds.
struct Lobe {
    double A = 0.0, B = 0.0, P = 0.0;
};

// Calls fn(h, wi, woh, weight) at every quadrature node with wo.h > 0 and wi.z > 0, where weight is the node's
// share of P22 ds (so that the sum of weight g(h) over the nodes integrates g against the NDF's projected measure).
template <class Fn>
void forEachHalfVector(double alpha, const glm::dvec3& wo, int nv, int nphi, Fn&& fn) {
    for (int i = 0; i < nv; ++i) {
        const double v = (i + 0.5) / nv, w = 1.0 - v, u = 1.0 - w * w;
        const double r = alpha * std::sqrt(u) / w;  // |s| = alpha sqrt(u / (1 - u)), 1 - u = w^2
        const double weight = 2.0 * w / nv / nphi;  // du = 2 w dv, P22 ds = du dphi / (2 pi)
        const double norm = std::sqrt(1.0 + r * r);
        for (int j = 0; j < nphi; ++j) {
            const double phi = 2.0 * kPi * (j + 0.5) / nphi;
            const double sx = r * std::cos(phi), sy = r * std::sin(phi);
            const glm::dvec3 h = glm::dvec3(-sx, -sy, 1.0) / norm;
            const double woh = glm::dot(wo, h);
            if (!(woh > 0.0)) continue;
            const glm::dvec3 wi = 2.0 * woh * h - wo;
            if (!(wi.z > 0.0)) continue;
            fn(h, wi, woh, weight, r);
        }
    }
}

Lobe lobeIntegrals(double alpha, const glm::dvec3& wo) {
    Lobe l;
    const double lo = lambda(wo.z, alpha);
    // The visible-normal weight: (wo.h) sqrt(1 + |s|^2) / wo.z = (wo.z - s.wo_xy) / wo.z.
    forEachHalfVector(alpha, wo, 1024, 256, [&](const glm::dvec3&, const glm::dvec3& wi, double woh, double weight, double r) {
        const double vis = woh * std::sqrt(1.0 + r * r) / wo.z * weight;
        const double g2 = 1.0 / (1.0 + lo + lambda(wi.z, alpha));
        const double m = 1.0 - woh, s = m * m * m * m * m;
        l.A += g2 * vis;
        l.B += s * g2 * vis;
        l.P += vis / (1.0 + lo);
    });
    return l;
}

struct SkyMaterial {
    const char* name;
    BsdfParams p;
};

std::vector<SkyMaterial> materials() {
    std::vector<SkyMaterial> m;
    auto add = [&](const char* name, float metallic, glm::vec3 base, float transmission) {
        BsdfParams p;
        p.metallic = metallic;
        p.baseColor = base;
        p.transmission = transmission;
        m.push_back({name, p});
    };
    add("white mirror", 1.0f, glm::vec3(1.0f), 0.0f);
    add("gold", 1.0f, glm::vec3(1.0f, 0.766f, 0.336f), 0.0f);
    add("clear coat on black", 0.0f, glm::vec3(0.0f), 0.0f);
    add("glossy plastic", 0.0f, glm::vec3(0.8f, 0.5f, 0.2f), 0.0f);
    add("thin glass", 0.0f, glm::vec3(1.0f), 1.0f);
    add("tinted thin glass", 0.0f, glm::vec3(0.9f, 0.6f, 0.3f), 1.0f);
    return m;
}

double schlick(double f0, double c) { return f0 + (1.0 - f0) * std::pow(1.0 - c, 5.0); }

// Reflected plus transmitted energy per channel from the lobe integrals; with A = 1 and B = (1 - cos)^5 (alpha -> 0)
// it is the closed form of the smooth surface.
glm::dvec3 expectedAlbedo(const BsdfParams& p, double cosO, double A, double B) {
    const double f0d = std::pow((double(p.ior) - 1.0) / (double(p.ior) + 1.0), 2.0);  // specularColor 1
    glm::dvec3 e;
    for (int k = 0; k < 3; ++k) {
        const double base = p.baseColor[k];
        const double metal = base * A + (1.0 - base) * B;
        const double spec = f0d * A + (1.0 - f0d) * B;  // specular 1
        const double diffuse = (1.0 - p.transmission) * base * (1.0 - schlick(f0d, cosO)) * (1.0 - f0d - (1.0 - f0d) / 21.0);
        const double trans = p.transmission * base * (A - spec);
        e[k] = p.metallic * metal + (1.0 - p.metallic) * (spec + diffuse + trans);
    }
    return e;
}

struct Estimate {
    glm::dvec3 mean{0.0}, stderr_{0.0};
};

// The path tracer's BSDF-sampled estimate of the albedo (PathTracer::extend: beta *= f * (|wi.ns| / pdf)),
// n samples: (u0, u1) jittered on a sqrt(n) x sqrt(n) grid, uLobe a shuffled jittered 1D stratification.
Estimate sampledAlbedo(const Bsdf& bsdf, const glm::vec3& wo, const glm::vec3& ns, int side, uint32_t seed) {
    std::mt19937 rng(seed);
    std::uniform_real_distribution<float> u01(0.0f, 1.0f);
    const int n = side * side;
    std::vector<float> lobe(static_cast<size_t>(n));
    for (int i = 0; i < n; ++i) lobe[size_t(i)] = std::min((float(i) + u01(rng)) / float(n), 0.99999994f);
    std::shuffle(lobe.begin(), lobe.end(), rng);
    const Bsdf::Outgoing out = bsdf.outgoing(wo);
    glm::dvec3 sum(0.0), sum2(0.0);
    for (int i = 0; i < side; ++i)
        for (int j = 0; j < side; ++j) {
            const glm::vec2 u(std::min((float(i) + u01(rng)) / float(side), 0.99999994f),
                              std::min((float(j) + u01(rng)) / float(side), 0.99999994f));
            const BsdfSample s = bsdf.sample(out, lobe[size_t(i * side + j)], u);
            if (!s.valid()) continue;
            const glm::dvec3 w(s.f * (std::abs(glm::dot(s.wi, ns)) / s.pdf));
            sum += w;
            sum2 += w * w;
        }
    Estimate e;
    e.mean = sum / double(n);
    const glm::dvec3 var = glm::max(sum2 / double(n) - e.mean * e.mean, glm::dvec3(0.0));
    e.stderr_ = glm::sqrt(var / double(n));
    return e;
}

// Integrals over the lobe of eval's f |wi.n| (reflected and, mirrored, transmitted) and of pdf, on the
// half-vector grid (each node weighted by 4 (wo.h) / (D(h) cos theta_h) of its P22 share, D in double): what
// next event estimation adds up and what MIS weighs it with, checked where the lobe is narrow.
void lobeQuadrature(const Bsdf& bsdf, const LocalFrame& fr, double alpha, const glm::dvec3& woLocal, glm::dvec3& evalIntegral,
                    double& pdfIntegral) {
    const glm::vec3 wo(fr.toWorld(woLocal));
    const glm::vec3 ns(fr.n);
    const Bsdf::Outgoing out = bsdf.outgoing(wo);
    evalIntegral = glm::dvec3(0.0);
    pdfIntegral = 0.0;
    const double a2 = alpha * alpha;
    forEachHalfVector(alpha, woLocal, 512, 128, [&](const glm::dvec3&, const glm::dvec3& wiLocal, double woh, double weight, double r) {
        const double t = 1.0 + r * r / a2;
        const double dCos = std::pow(1.0 + r * r, 1.5) / (kPi * a2 * t * t);  // D(h) cos(theta_h)
        const double jac = 4.0 * woh / dCos * weight;
        for (int side : {1, -1}) {
            if (side < 0 && !bsdf.transmits()) break;
            const glm::vec3 wi(fr.toWorld(glm::dvec3(wiLocal.x, wiLocal.y, side * wiLocal.z)));
            evalIntegral += glm::dvec3(bsdf.eval(out, wi)) * (std::abs(double(glm::dot(wi, ns))) * jac);
            pdfIntegral += double(bsdf.pdf(out, wi)) * jac;
        }
    });
}

// wo in the local frame, deg from the normal (at an azimuth off the frame's axes).
glm::dvec3 viewDirection(double deg) {
    const double th = deg * kPi / 180.0;
    return {std::sin(th) * std::cos(0.7), std::sin(th) * std::sin(0.7), std::cos(th)};
}

TEST(SmoothBsdf, UniformSkyGivesTheFresnelIntegral) {
    const LocalFrame fr = localFrame();
    const glm::vec3 ns(fr.n);
    const std::vector<SkyMaterial> mats = materials();
    int failures = 0;
    double worstClosed = 0.0;
    std::string table;
    double lobesAlpha = -1.0;
    std::vector<Lobe> lobes;  // per view angle, for alpha lobesAlpha (roughness 0, 0.001 and 0.01 share alpha 1e-3)
    for (float roughness : kRoughness) {
        const double alpha = double(std::max(roughness * roughness, Bsdf::kMinAlpha));
        if (alpha != lobesAlpha) {
            lobes.clear();
            for (double deg : kViewDegrees) lobes.push_back(lobeIntegrals(alpha, viewDirection(deg)));
            lobesAlpha = alpha;
        }
        for (size_t v = 0; v < std::size(kViewDegrees); ++v) {
            const double deg = kViewDegrees[v];
            const glm::dvec3 woLocal = viewDirection(deg);
            const glm::vec3 wo(fr.toWorld(woLocal));
            const Lobe& lobe = lobes[v];
            char row[256];
            std::snprintf(row, sizeof(row), "roughness %5.3f  %2.0f deg  A %.5f:", roughness, deg, lobe.A);
            table += row;
            for (size_t m = 0; m < mats.size(); ++m) {
                BsdfParams p = mats[m].p;
                p.roughness = roughness;
                const Bsdf bsdf(Frame::fromNormal(ns), p);
                ASSERT_EQ(float(alpha), bsdf.alpha());
                const glm::dvec3 model = expectedAlbedo(p, woLocal.z, lobe.A, lobe.B);
                const glm::dvec3 closed = expectedAlbedo(p, woLocal.z, 1.0, std::pow(1.0 - woLocal.z, 5.0));
                const Estimate est = sampledAlbedo(bsdf, wo, ns, 256, 1000u + uint32_t(m));
                std::snprintf(row, sizeof(row), " %.4f", est.mean.x);
                table += row;
                // The model's own departure from the smooth closed form (see the top): within 0.3% but at
                // roughness 0.1 seen at 80 and 85 degrees.
                const bool nearSmooth = alpha < 0.005 || deg < 75.0;
                for (int k = 0; k < 3; ++k) {
                    const std::string where = std::string(mats[m].name) + " roughness " + std::to_string(roughness) +
                                              " view " + std::to_string(deg) + " channel " + std::to_string(k);
                    // The estimate is the model's value (noise: 5 standard errors of the unstratified estimate,
                    // an upper bound for this stratified one, and 2e-4 of float rounding and quadrature).
                    const double noise = 5.0 * est.stderr_[k] + 2e-4 * model[k];
                    if (!(std::abs(est.mean[k] - model[k]) <= noise)) ++failures;
                    EXPECT_NEAR(est.mean[k], model[k], noise) << where;
                    if (nearSmooth) {
                        EXPECT_NEAR(model[k], closed[k], 3e-3 * closed[k]) << where;
                        EXPECT_NEAR(est.mean[k], closed[k], 3e-3 * closed[k]) << where;
                        worstClosed = std::max(worstClosed, std::abs(est.mean[k] / closed[k] - 1.0));
                    } else {
                        // Less than the smooth surface's, never more (no energy created), and by the known amount.
                        EXPECT_LE(model[k], closed[k]) << where;
                        EXPECT_GE(model[k], 0.97 * closed[k]) << where;
                    }
                }
                // NEE and MIS: eval integrates to the same energy and pdf to the fraction of valid samples, where
                // the lobe alone is sampled (no diffuse base to integrate on the half-vector grid).
                if (p.metallic == 1.0f || p.transmission == 1.0f) {
                    glm::dvec3 evalIntegral;
                    double pdfIntegral;
                    lobeQuadrature(bsdf, fr, alpha, woLocal, evalIntegral, pdfIntegral);
                    for (int k = 0; k < 3; ++k)
                        EXPECT_NEAR(evalIntegral[k], model[k], 1e-3 * model[k])
                            << mats[m].name << " eval, roughness " << roughness << " view " << deg << " channel " << k;
                    EXPECT_NEAR(pdfIntegral, lobe.P, 1e-3) << mats[m].name << " pdf, roughness " << roughness << " view " << deg;
                }
            }
            table += "\n";
        }
    }
    std::printf("sampled albedo (red channel) of: white mirror, gold, clear coat on black, glossy plastic, thin glass, "
                "tinted thin glass\n%sworst deviation from the closed form where the model is within 0.3%% of it: %.5f\n",
                table.c_str(), worstClosed);
    EXPECT_EQ(failures, 0);
}

// The same through the path tracer (next event estimation of the sky, BSDF sampling and MIS): a smooth white
// metal plane and a thin clear sheet under a uniform sky of radiance 1 give back 1 (the metal reflects all of it;
// the sheet reflects F and passes 1 - F of the sky behind it) seen at 0, 45 and 80 degrees; gold reflects its
// Schlick F. Before issue 37's fix the mirror was 0.949 at normal incidence.
TEST(SmoothBsdf, SmoothSurfacesUnderAUniformSkyRenderTheirFresnel) {
    ThreadScope threads(0);
    struct Surface {
        const char* name;
        float metallic, transmission, roughness;
        glm::vec3 base;
    };
    const Surface surfaces[] = {{"white mirror", 1.0f, 0.0f, 0.0f, glm::vec3(1.0f)},
                                {"white metal, roughness 0.05", 1.0f, 0.0f, 0.05f, glm::vec3(1.0f)},
                                {"gold", 1.0f, 0.0f, 0.0f, glm::vec3(1.0f, 0.766f, 0.336f)},
                                {"thin glass", 0.0f, 1.0f, 0.0f, glm::vec3(1.0f)}};
    for (const Surface& surface : surfaces)
        for (double deg : {0.0, 45.0, 80.0}) {
            Scene scene = test::makeLitPlane(1.0f, 10.0f);
            Material& m = scene.materials[0];
            m.metallic = surface.metallic;
            m.transmission = surface.transmission;
            m.roughness = surface.roughness;
            m.baseColor = surface.base;
            m.specular = 1.0f;
            m.doubleSided = true;
            scene.environment = defaultSky();
            const double th = deg * kPi / 180.0;
            const glm::vec3 back(float(std::sin(th)), 0.0f, float(std::cos(th))), right(0.0f, 1.0f, 0.0f);
            Camera& camera = scene.cameras[0];
            camera.worldFromCamera = glm::mat3(right, glm::cross(back, right), back);
            camera.position = 5.0f * back;
            camera.xmag = camera.ymag = 0.25f;
            const glm::dvec3 mean = test::renderPathTraced(scene, 8, 256).mean();
            const double c = std::cos(th);
            for (int k = 0; k < 3; ++k) {
                const double expected = surface.metallic == 1.0f ? schlick(surface.base[k], c) : 1.0;
                EXPECT_NEAR(mean[k], expected, 3e-3 * expected) << surface.name << " at " << deg << " degrees, channel " << k;
            }
        }
}

}  // namespace
}  // namespace nrad
