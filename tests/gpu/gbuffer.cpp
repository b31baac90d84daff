#include "gpu/gbuffer.h"

#include <nrad/eval.h>

#include "baker/render/camera.h"
#include "baker/render/surface.h"

namespace nrad {

Camera defaultCamera(const Scene& scene) { return scene.cameras.empty() ? frameBounds(scene.bounds) : scene.cameras[0]; }

GBuffer renderGBuffer(const Scene& scene, const Accel& accel, int width, int height) {
    GBuffer g;
    g.width = width;
    g.height = height;
    CameraRays rays(defaultCamera(scene), width, height);
    for (int y = 0; y < height; ++y)
        for (int x = 0; x < width; ++x) {
            glm::vec3 o, d;
            rays.generate(float(x) + 0.5f, float(y) + 0.5f, o, d);
            const Hit hit = accel.intersect(o, d);
            if (!hit.valid()) continue;
            const SurfaceInteraction si = makeInteraction(scene, hit, d);
            const eval::Surface e = shadingSurface(si);
            NradSurface s;
            for (int c = 0; c < 3; ++c) {
                s.baseColor[c] = e.baseColor[c];
                s.emission[c] = e.emission[c];
            }
            s.metallic = e.metallic;
            s.roughness = e.roughness;
            s.specular = e.specular;
            g.add(si.p, si.ns, si.wo, s);
            g.pixel.push_back(uint32_t(y * width + x));
        }
    return g;
}

}  // namespace nrad
