// The stiff furnace: albedo 0.99, a Neumann series that converges slowly (mean path length 100).
#include <gtest/gtest.h>

#include "baker/render/accel.h"
#include "baker/lights/light_sampler.h"
#include "baker/render/path_tracer.h"
#include "baker/util/threads.h"
#include "support/test_scenes.h"

namespace nrad {
namespace {

TEST(DiffuseFurnaceSlow, AlbedoPoint99) {
    ThreadScope threads(0);
    Material m;
    m.baseColor = glm::vec3(0.99f);
    m.metallic = 0.0f;
    m.specular = 0.0f;
    m.emission = glm::vec3(1.0f);
    Scene scene = test::makeSphereFurnace(m);
    Accel accel(scene);
    LightSampler lights(scene);
    PathTracer tracer(scene, accel, lights);
    RenderSettings s;
    s.width = s.height = 2;
    s.spp = 1 << 19;
    s.tileSize = 1;
    Image image = tracer.render(scene.cameras[0], s);
    // Le / (1 - a) = 100. Per-pixel standard error about 0.14%; the whole image within 1%.
    EXPECT_NEAR(image.mean().x / 100.0, 1.0, 0.01);
    for (const glm::vec3& p : image.pixels) EXPECT_NEAR(p.x / 100.0, 1.0, 0.01);
}

}  // namespace
}  // namespace nrad
