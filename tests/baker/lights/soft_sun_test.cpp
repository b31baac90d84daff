// Soft suns (issue 37, item 4): a disk of angular radius r and uniform radiance Le = E / (pi sin^2 r) gives a
// plane whose normal is beta from the disk's centre (the disk wholly above the plane) the irradiance
// integral Le cos = Le pi sin^2 r cos(beta) = E cos(beta), exactly (the cosine-weighted solid angle of a
// spherical cap is pi sin^2 r times the cosine of its axis). The disk is the cap cos >= cosAngularRadius, the
// float the scene holds, so sin^2 r is (1 - c)(1 + c) of that float. Computed as 1 - c * c in float, a 2-degree
// sun's sin^2 (3e-4) lost the rounding of c * c (up to 3e-8, i.e. 1e-4 of it): its irradiance came out 7.5e-5
// low, a 20-degree one's exact. Next event estimation's estimate (Li cos / pdf over the sample's cone, on a
// grid of sample points whose midpoint rule is exact for it) and the radiance a ray meets in the disk must
// give E cos(beta) within 1e-6.
#include <algorithm>
#include <cmath>
#include <cstdio>

#include <gtest/gtest.h>

#include "baker/lights/light.h"
#include "baker/lights/light_sampler.h"
#include "baker/scene/scene.h"

namespace nrad {
namespace {

constexpr double kPi = 3.14159265358979323846;

TEST(SoftSun, IrradianceIsTheClosedFormToOnePartInAMillion) {
    const double E = 3.0;
    double worst = 0.0;
    for (double diameterDeg : {0.53, 1.0, 2.0, 5.0, 20.0}) {
        Scene scene;
        scene.bounds.extend(glm::vec3(-1.0f));
        scene.bounds.extend(glm::vec3(1.0f));
        PunctualLight sun;
        sun.type = PunctualLight::Type::Directional;
        sun.direction = glm::normalize(glm::vec3(0.2f, -0.3f, -0.9f));
        sun.intensity = glm::vec3(float(E));
        // As the command line's --sun-angle sets it (baker/cmd/scene_loading.cpp).
        sun.cosAngularRadius = float(std::cos(0.5 * diameterDeg * kPi / 180.0));
        scene.lights.push_back(sun);
        const LightSampler lights(scene);
        ASSERT_EQ(lights.lightCount(), 1u);
        const Light& light = lights.light(0);
        const double c = sun.cosAngularRadius, sin2 = (1.0 - c) * (1.0 + c);
        const glm::dvec3 axis = -glm::dvec3(sun.direction);

        // The radiance a ray meets inside the disk (BSDF-sampled rays, and camera rays through skyRadiance).
        glm::vec3 Le(0.0f);
        float escapedPdf = 0.0f;
        ASSERT_TRUE(light.escaped(-sun.direction, Le, escapedPdf));
        EXPECT_NEAR(double(Le.x) * kPi * sin2 / E, 1.0, 1e-6) << diameterDeg << " degrees";
        worst = std::max(worst, std::abs(double(Le.x) * kPi * sin2 / E - 1.0));
        EXPECT_NEAR(double(skyRadiance(scene, -sun.direction).x) * kPi * sin2 / E, 1.0, 1e-6) << diameterDeg << " degrees";
        EXPECT_NEAR(double(escapedPdf) * 2.0 * kPi * (1.0 - c), 1.0, 1e-6) << diameterDeg << " degrees";

        // Next event estimation on planes tilted 0, 30 and 60 degrees from the disk's centre.
        const glm::dvec3 side = glm::normalize(glm::cross(axis, glm::dvec3(0.0, 0.0, 1.0)));
        for (double betaDeg : {0.0, 30.0, 60.0}) {
            const double beta = betaDeg * kPi / 180.0;
            const glm::dvec3 n = std::cos(beta) * axis + std::sin(beta) * side;
            const int nu = 256, nphi = 64;
            double sum = 0.0;
            for (int i = 0; i < nu; ++i)
                for (int j = 0; j < nphi; ++j) {
                    const LightSample ls = light.sample(glm::vec3(0.0f), glm::vec2(float((i + 0.5) / nu), float((j + 0.5) / nphi)));
                    ASSERT_GT(ls.pdf, 0.0f);
                    ASSERT_GE(glm::dot(glm::dvec3(ls.wi), axis), c - 1e-7);
                    sum += double(ls.Li.x) * std::max(0.0, glm::dot(glm::dvec3(ls.wi), n)) / double(ls.pdf);
                }
            const double irradiance = sum / (nu * nphi);
            EXPECT_NEAR(irradiance / (E * std::cos(beta)), 1.0, 1e-6) << diameterDeg << " degrees, plane at " << betaDeg;
            worst = std::max(worst, std::abs(irradiance / (E * std::cos(beta)) - 1.0));
        }
    }
    std::printf("largest relative error of the disk's radiance and irradiance: %.3g\n", worst);
}

}  // namespace
}  // namespace nrad
