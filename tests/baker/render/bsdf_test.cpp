// BSDF: sample() against pdf() (chi-square on a histogram), pdf integrates to one, reciprocity, energy
// (white-furnace albedo <= 1, by quadrature and by importance sampling, which must agree), and the
// Lambertian case in closed form.
#include "baker/render/bsdf.h"
#include "baker/render/sincos.h"

#include <cmath>
#include <random>
#include <vector>

#include <gtest/gtest.h>

namespace nrad {
namespace {

constexpr double kPi = 3.14159265358979323846;

glm::vec3 dirFromAngles(double theta, double phi) {
    return glm::vec3(float(std::sin(theta) * std::cos(phi)), float(std::sin(theta) * std::sin(phi)), float(std::cos(theta)));
}

Bsdf makeBsdf(const BsdfParams& p) { return Bsdf(Frame::fromNormal(glm::vec3(0, 0, 1)), p); }

// Directional albedo E(wo) = integral of f cos over the hemisphere, by midpoint quadrature in (cos theta, phi).
glm::dvec3 albedoQuadrature(const Bsdf& bsdf, const glm::vec3& wo, int n = 1024) {
    glm::dvec3 sum(0.0);
    for (int i = 0; i < n; ++i) {
        double cosTheta = (i + 0.5) / n;
        double theta = std::acos(cosTheta);
        for (int j = 0; j < 2 * n; ++j) {
            double phi = 2.0 * kPi * (j + 0.5) / (2 * n);
            glm::vec3 wi = dirFromAngles(theta, phi);
            sum += glm::dvec3(bsdf.eval(wo, wi)) * cosTheta;
        }
    }
    return sum * (1.0 / n) * (2.0 * kPi / (2 * n));
}

// The same integral estimated by importance sampling: mean of f cos / pdf.
glm::dvec3 albedoSampled(const Bsdf& bsdf, const glm::vec3& wo, int n, uint32_t seed) {
    std::mt19937 rng(seed);
    std::uniform_real_distribution<float> u(0.0f, 1.0f);
    glm::dvec3 sum(0.0);
    for (int i = 0; i < n; ++i) {
        BsdfSample s = bsdf.sample(wo, u(rng), {u(rng), u(rng)});
        if (!s.valid()) continue;
        sum += glm::dvec3(s.f) * double(s.wi.z) / double(s.pdf);
    }
    return sum / double(n);
}

struct Case {
    float metallic, roughness, specular;
    glm::vec3 base;
};

const Case kCases[] = {
    {0.0f, 1.0f, 1.0f, glm::vec3(0.8f)},    {0.0f, 0.5f, 1.0f, glm::vec3(0.5f, 0.2f, 0.1f)},
    {0.0f, 0.2f, 1.0f, glm::vec3(0.7f)},    {1.0f, 1.0f, 1.0f, glm::vec3(1.0f)},
    {1.0f, 0.5f, 1.0f, glm::vec3(1.0f)},    {1.0f, 0.3f, 1.0f, glm::vec3(0.95f, 0.64f, 0.54f)},
    {0.5f, 0.4f, 1.0f, glm::vec3(0.9f)},    {0.0f, 1.0f, 0.0f, glm::vec3(0.6f)},
};

BsdfParams paramsOf(const Case& c) {
    BsdfParams p;
    p.metallic = c.metallic;
    p.roughness = c.roughness;
    p.specular = c.specular;
    p.baseColor = c.base;
    return p;
}

// The sampling angle's sine and cosine (sincos.h): within 1.5e-7 of double precision's over |phi| <= 8, on a
// fine grid and at the quadrant boundaries, where the reduction changes polynomial and sign.
TEST(SinCos, AgreesWithDoublePrecision) {
    double worst = 0.0;
    float worstPhi = 0.0f;
    auto check = [&](float phi) {
        float s, c;
        sinCos(phi, s, c);
        const double e = std::max(std::abs(double(s) - std::sin(double(phi))), std::abs(double(c) - std::cos(double(phi))));
        if (!(e <= worst)) {
            worst = e;
            worstPhi = phi;
        }
    };
    for (int i = -400000; i <= 400000; ++i) check(float(i) * 2e-5f);
    for (int k = -5; k <= 5; ++k)
        for (int d = -64; d <= 64; ++d) check(std::nextafter(float(k * kPi / 4.0), 0.0f) + float(d) * 1e-7f);
    check(float(2.0 * kPi) - 1e-6f);
    EXPECT_LE(worst, 1.5e-7) << "at phi = " << worstPhi;  // 7.5e-8 measured; libm's float sin and cos: 3.3e-8
    // The signs follow the quadrant.
    float s, c;
    sinCos(float(3.0 * kPi / 4.0), s, c);
    EXPECT_GT(s, 0.0f);
    EXPECT_LT(c, 0.0f);
    sinCos(float(-kPi / 2.0), s, c);
    EXPECT_NEAR(s, -1.0f, 1e-7f);
    EXPECT_NEAR(c, 0.0f, 1e-7f);
}

TEST(Bsdf, LambertianAlbedoIsTheBaseColour) {
    BsdfParams p;
    p.baseColor = glm::vec3(0.2f, 0.5f, 0.9f);
    p.metallic = 0.0f;
    p.specular = 0.0f;  // KHR_materials_specular factor 0: pure Lambertian
    Bsdf bsdf = makeBsdf(p);
    for (double theta : {0.0, 0.6, 1.2, 1.5}) {
        glm::vec3 wo = dirFromAngles(theta, 0.3);
        glm::dvec3 e = albedoQuadrature(bsdf, wo, 256);
        EXPECT_NEAR(e.x, 0.2, 1e-4);
        EXPECT_NEAR(e.y, 0.5, 1e-4);
        EXPECT_NEAR(e.z, 0.9, 1e-4);
        // Cosine sampling of a Lambertian lobe has zero variance: every sample weight is the albedo.
        BsdfSample s = bsdf.sample(wo, 0.5f, {0.3f, 0.7f});
        ASSERT_TRUE(s.valid());
        glm::vec3 w = s.f * s.wi.z / s.pdf;
        EXPECT_NEAR(w.y, 0.5f, 1e-5f);
    }
}

TEST(Bsdf, PdfIntegratesToTheFractionOfValidSamples) {
    // Visible-normal sampling reflects some directions below the horizon (sample() then fails), so the pdf
    // of the valid directions integrates to the probability that sample() succeeds: one for pure diffuse,
    // exactly 1/2 for a metal at alpha 1 seen at normal incidence (cosine-distributed normals, valid when
    // cos(theta_h) > 1/sqrt(2)).
    std::mt19937 rng(1);
    std::uniform_real_distribution<float> u(0.0f, 1.0f);
    for (const Case& c : kCases) {
        Bsdf bsdf = makeBsdf(paramsOf(c));
        for (double theta : {0.0, 0.8, 1.3}) {
            glm::vec3 wo = dirFromAngles(theta, 1.0);
            int n = c.roughness < 0.35f ? 2048 : 512;
            double sum = 0.0;
            for (int i = 0; i < n; ++i) {
                double ct = (i + 0.5) / n, th = std::acos(ct);
                for (int j = 0; j < 2 * n; ++j) sum += bsdf.pdf(wo, dirFromAngles(th, 2.0 * kPi * (j + 0.5) / (2 * n)));
            }
            sum *= (1.0 / n) * (2.0 * kPi / (2 * n));
            int valid = 0, samples = 200000;
            for (int i = 0; i < samples; ++i) valid += bsdf.sample(wo, u(rng), {u(rng), u(rng)}).valid() ? 1 : 0;
            EXPECT_NEAR(sum, double(valid) / samples, 5e-3) << "metallic " << c.metallic << " roughness " << c.roughness
                                                           << " theta " << theta;
            EXPECT_LE(sum, 1.0 + 2e-3);
            if (c.metallic == 1.0f && c.roughness == 1.0f && theta == 0.0) {
                EXPECT_NEAR(sum, 0.5, 2e-3);
            }
            if (c.metallic == 0.0f && c.specular == 0.0f) {
                EXPECT_NEAR(sum, 1.0, 2e-3);
            }
        }
    }
}

TEST(Bsdf, SampledDirectionsFollowThePdf) {
    // Chi-square test of a histogram of sample() against the integrated pdf() over (cos theta, phi) bins.
    const int kThetaBins = 16, kPhiBins = 32, kSamples = 400000;
    std::mt19937 rng(7);
    std::uniform_real_distribution<float> u(0.0f, 1.0f);
    for (const Case& c : kCases) {
        Bsdf bsdf = makeBsdf(paramsOf(c));
        glm::vec3 wo = dirFromAngles(0.7, 0.4);
        std::vector<double> observed(kThetaBins * kPhiBins, 0.0), expected(kThetaBins * kPhiBins, 0.0);
        int valid = 0;
        for (int i = 0; i < kSamples; ++i) {
            BsdfSample s = bsdf.sample(wo, u(rng), {u(rng), u(rng)});
            if (!s.valid()) continue;
            ++valid;
            double ct = std::clamp(double(s.wi.z), 0.0, 1.0 - 1e-9);
            double phi = std::atan2(double(s.wi.y), double(s.wi.x));
            if (phi < 0) phi += 2 * kPi;
            int bi = std::min(kThetaBins - 1, int(ct * kThetaBins));
            int bj = std::min(kPhiBins - 1, int(phi / (2 * kPi) * kPhiBins));
            observed[size_t(bi * kPhiBins + bj)] += 1.0;
        }
        const int sub = 12;
        for (int bi = 0; bi < kThetaBins; ++bi)
            for (int bj = 0; bj < kPhiBins; ++bj) {
                double acc = 0.0;
                for (int a = 0; a < sub; ++a)
                    for (int b = 0; b < sub; ++b) {
                        double ct = (bi + (a + 0.5) / sub) / kThetaBins;
                        double phi = 2 * kPi * (bj + (b + 0.5) / sub) / kPhiBins;
                        acc += bsdf.pdf(wo, dirFromAngles(std::acos(ct), phi));
                    }
                double binArea = (1.0 / kThetaBins) * (2 * kPi / kPhiBins);
                expected[size_t(bi * kPhiBins + bj)] = acc / (sub * sub) * binArea * kSamples;
            }
        // Pool bins with small expectation, then chi-square.
        double chi2 = 0.0, pooledObs = 0.0, pooledExp = 0.0;
        int dof = -1;
        for (size_t k = 0; k < observed.size(); ++k) {
            if (expected[k] < 5.0) {
                pooledObs += observed[k];
                pooledExp += expected[k];
                continue;
            }
            chi2 += (observed[k] - expected[k]) * (observed[k] - expected[k]) / expected[k];
            ++dof;
        }
        if (pooledExp >= 5.0) {
            chi2 += (pooledObs - pooledExp) * (pooledObs - pooledExp) / pooledExp;
            ++dof;
        }
        // Wilson-Hilferty: chi2/dof is approximately normal; reject beyond 5 sigma (p ~ 3e-7).
        double k = dof;
        double z = (std::cbrt(chi2 / k) - (1.0 - 2.0 / (9.0 * k))) / std::sqrt(2.0 / (9.0 * k));
        EXPECT_LT(z, 5.0) << "metallic " << c.metallic << " roughness " << c.roughness << " chi2 " << chi2 << " dof " << dof;
        EXPECT_GT(valid, kSamples / 2);
    }
}

TEST(Bsdf, SampleWeightMatchesEvalOverPdf) {
    std::mt19937 rng(3);
    std::uniform_real_distribution<float> u(0.0f, 1.0f);
    for (const Case& c : kCases) {
        Bsdf bsdf = makeBsdf(paramsOf(c));
        glm::vec3 wo = dirFromAngles(0.9, 2.0);
        for (int i = 0; i < 1000; ++i) {
            BsdfSample s = bsdf.sample(wo, u(rng), {u(rng), u(rng)});
            if (!s.valid()) continue;
            glm::vec3 f = bsdf.eval(wo, s.wi);
            ASSERT_NEAR(f.x, s.f.x, 1e-5f * std::max(1.0f, f.x));
            ASSERT_NEAR(bsdf.pdf(wo, s.wi), s.pdf, 1e-5f * std::max(1.0f, s.pdf));
        }
    }
}

TEST(Bsdf, Reciprocity) {
    std::mt19937 rng(11);
    std::uniform_real_distribution<double> u(0.0, 1.0);
    for (const Case& c : kCases) {
        Bsdf bsdf = makeBsdf(paramsOf(c));
        for (int i = 0; i < 500; ++i) {
            glm::vec3 a = dirFromAngles(std::acos(u(rng)), 2 * kPi * u(rng));
            glm::vec3 b = dirFromAngles(std::acos(u(rng)), 2 * kPi * u(rng));
            glm::vec3 fab = bsdf.eval(a, b), fba = bsdf.eval(b, a);
            for (int k = 0; k < 3; ++k) ASSERT_NEAR(fab[k], fba[k], 1e-5f * std::max(1.0f, fab[k]));
        }
    }
}

TEST(Bsdf, WhiteFurnaceEnergyAtMostOneAndSamplingAgreesWithQuadrature) {
    for (const Case& c : kCases) {
        BsdfParams p = paramsOf(c);
        p.baseColor = glm::vec3(1.0f);  // white furnace
        Bsdf bsdf = makeBsdf(p);
        for (double theta : {0.0, 0.7, 1.2, 1.45}) {
            glm::vec3 wo = dirFromAngles(theta, 0.0);
            int n = c.roughness < 0.35f ? 2048 : 768;
            glm::dvec3 q = albedoQuadrature(bsdf, wo, n);
            glm::dvec3 s = albedoSampled(bsdf, wo, 200000, 5);
            for (int k = 0; k < 3; ++k) {
                EXPECT_LE(q[k], 1.0 + 1e-3) << "metallic " << c.metallic << " roughness " << c.roughness;
                EXPECT_NEAR(s[k], q[k], 0.01 * q[k] + 1e-3) << "metallic " << c.metallic << " roughness "
                                                            << c.roughness << " theta " << theta;
            }
        }
    }
}

TEST(Bsdf, RoughMetalLosesTheKnownSingleScatteringEnergy) {
    // White metal at alpha = 1: D = 1/pi, and at normal incidence Lambda(wo) = 0 and
    // G2 = 2 mu / (1 + mu), so f cos = 1 / (2 pi (1 + mu)) mu and E = integral_0^1 mu / (1 + mu) dmu = 1 - ln 2.
    BsdfParams p;
    p.metallic = 1.0f;
    p.roughness = 1.0f;
    p.baseColor = glm::vec3(1.0f);
    Bsdf bsdf = makeBsdf(p);
    double e = albedoQuadrature(bsdf, glm::vec3(0, 0, 1), 1024).x;
    EXPECT_NEAR(e, 1.0 - std::log(2.0), 1e-4);
    EXPECT_NEAR(albedoSampled(bsdf, glm::vec3(0, 0, 1), 400000, 9).x, 1.0 - std::log(2.0), 3e-3);
    // Smoother surfaces lose less.
    p.roughness = 0.3f;
    double eSmooth = albedoQuadrature(makeBsdf(p), glm::vec3(0, 0, 1), 2048).x;
    EXPECT_GT(eSmooth, 0.97);
    EXPECT_LE(eSmooth, 1.0);
}

}  // namespace
}  // namespace nrad

namespace nrad {
namespace {

// Thin-walled transmission (KHR_materials_transmission): over the whole sphere, sampling agrees with the pdf
// and with eval / pdf, the energy (reflected + transmitted, white furnace) is at most one and importance
// sampling agrees with quadrature, and a fully transmissive clear sheet (specular 0) passes almost all light.
glm::dvec3 sphereQuadrature(const Bsdf& bsdf, const glm::vec3& wo, int n, double* pdfIntegral) {
    glm::dvec3 sum(0.0);
    double pdfSum = 0.0;
    for (int i = 0; i < 2 * n; ++i) {
        double cosTheta = -1.0 + (i + 0.5) / n;
        double theta = std::acos(cosTheta);
        for (int j = 0; j < 2 * n; ++j) {
            double phi = 2.0 * kPi * (j + 0.5) / (2 * n);
            glm::vec3 wi = dirFromAngles(theta, phi);
            sum += glm::dvec3(bsdf.eval(wo, wi)) * std::abs(cosTheta);
            pdfSum += bsdf.pdf(wo, wi);
        }
    }
    const double cell = (1.0 / n) * (2.0 * kPi / (2 * n));
    *pdfIntegral = pdfSum * cell;
    return sum * cell;
}

TEST(BsdfTransmission, EnergyPdfAndSamplingOverTheWholeSphere) {
    std::mt19937 rng(21);
    std::uniform_real_distribution<float> u(0.0f, 1.0f);
    for (float transmission : {0.5f, 1.0f})
        for (float roughness : {0.3f, 0.7f}) {
            BsdfParams p;
            p.metallic = 0.0f;
            p.roughness = roughness;
            p.transmission = transmission;
            p.baseColor = glm::vec3(1.0f);
            Bsdf bsdf = makeBsdf(p);
            ASSERT_TRUE(bsdf.transmits());
            for (double theta : {0.2, 0.9, 1.3}) {
                glm::vec3 wo = dirFromAngles(theta, 0.5);
                double pdfIntegral;
                glm::dvec3 q = sphereQuadrature(bsdf, wo, 512, &pdfIntegral);
                glm::dvec3 sampled(0.0), below(0.0);
                int valid = 0, n = 200000;
                for (int i = 0; i < n; ++i) {
                    BsdfSample s = bsdf.sample(wo, u(rng), {u(rng), u(rng)});
                    if (!s.valid()) continue;
                    ++valid;
                    glm::vec3 f = bsdf.eval(wo, s.wi);
                    ASSERT_NEAR(f.x, s.f.x, 1e-5f * std::max(1.0f, f.x));
                    ASSERT_NEAR(bsdf.pdf(wo, s.wi), s.pdf, 1e-4f * std::max(1.0f, s.pdf));
                    glm::dvec3 w = glm::dvec3(s.f) * std::abs(double(s.wi.z)) / double(s.pdf);
                    sampled += w;
                    if (s.wi.z < 0.0f) below += w;
                }
                sampled /= double(n);
                below /= double(n);
                const std::string what = "T " + std::to_string(transmission) + " roughness " + std::to_string(roughness) +
                                         " theta " + std::to_string(theta);
                EXPECT_NEAR(pdfIntegral, double(valid) / n, 5e-3) << what;
                EXPECT_LE(q.x, 1.0 + 1e-3) << what;
                EXPECT_NEAR(sampled.x, q.x, 0.01 * q.x + 1e-3) << what;
                EXPECT_GT(below.x, 0.2 * transmission) << what;  // light really passes through
            }
        }
    // A clear sheet: fully transmissive, no specular layer, nearly smooth: nearly everything passes straight
    // through (the GGX lobe's single-scattering loss only).
    BsdfParams clear;
    clear.metallic = 0.0f;
    clear.specular = 0.0f;
    clear.transmission = 1.0f;
    clear.roughness = 0.05f;
    Bsdf sheet = makeBsdf(clear);
    double pdfIntegral;
    glm::vec3 wo = dirFromAngles(0.4, 0.0);
    glm::dvec3 q = sphereQuadrature(sheet, wo, 2048, &pdfIntegral);
    EXPECT_NEAR(q.x, 1.0, 0.01);
    EXPECT_EQ(sheet.eval(wo, glm::vec3(0, 0, 1)), glm::vec3(0.0f));  // nothing reflected diffusely
}

}  // namespace
}  // namespace nrad
