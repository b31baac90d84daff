// The runtime's shading contracts applied point by point to what an asset returned: the reference every shaded
// result (CPU G-buffers, GLSL, HLSL) is held to.
#pragma once

#include <cmath>
#include <cstddef>
#include <cstdint>

#include <nrad/eval.h>
#include <nrad/nrad.h>

namespace nrad::test {

// nradShadeBatch's contract (docs/runtime.md, "Shading contract"): eval::shade with non-finite emission terms as 0,
// the cosine of normal and direction (0 if not finite), non-finite results as 0. With `volume`, the volume query's
// (eval::shadeVolume; contentFlags unused). rgb: the asset's values in, the shaded radiance out.
inline void shadeReference(uint32_t contentFlags, size_t count, const float* n, const float* d, const NradSurface* surfaces,
                           float* rgb, bool volume = false) {
    for (size_t i = 0; i < count; ++i) {
        const NradSurface& in = surfaces[i];
        eval::Surface s;
        for (int c = 0; c < 3; ++c) {
            s.baseColor[c] = in.baseColor[c];
            s.emission[c] = std::isfinite(in.emission[c]) ? in.emission[c] : 0.0f;
        }
        s.metallic = in.metallic;
        s.roughness = in.roughness;
        s.specular = in.specular;
        const float* nn = n + 3 * i;
        const float* dd = d + 3 * i;
        const float cosNV = nn[0] * dd[0] + nn[1] * dd[1] + nn[2] * dd[2];
        float out[3];
        if (volume) eval::shadeVolume(rgb + 3 * i, s, std::isfinite(cosNV) ? cosNV : 0.0f, out);
        else eval::shade(contentFlags, rgb + 3 * i, s, std::isfinite(cosNV) ? cosNV : 0.0f, out);
        for (int c = 0; c < 3; ++c) rgb[3 * i + size_t(c)] = std::isfinite(out[c]) ? out[c] : 0.0f;
    }
}

}  // namespace nrad::test
