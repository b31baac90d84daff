// The G-buffer the runtime benchmarks shade (runtime_bench's G-buffer table, frame_bench): texels as an engine
// holds them (position fp32, normal and direction fp16, padded to 28 bytes), shaded 4096 at a time (a 64 x 64
// tile from a job system) into RGBA fp16.
#pragma once

#include <cstddef>
#include <cstdint>
#include <cstring>
#include <vector>

#include <nrad/nrad.h>

namespace nrad::bench {

struct Texel {
    float position[3];
    uint16_t normal[4], direction[4];
};

constexpr size_t kTilePixels = 64 * 64;

// Texels [first, first + kTilePixels) (fewer at the end) into `rgba` (4 halves per texel, from texel 0), unit
// vectors, shaded with `surfaces` (from texel 0) when given.
inline NradGBuffer describeTile(const std::vector<Texel>& texels, size_t first, uint16_t* rgba,
                                const NradSurface* surfaces = nullptr) {
    NradGBuffer g;
    std::memset(&g, 0, sizeof g);
    g.structSize = sizeof g;
    g.flags = NRAD_GBUFFER_UNIT_VECTORS;
    g.count = texels.size() - first < kTilePixels ? texels.size() - first : kTilePixels;
    g.position = {texels[first].position, sizeof(Texel), NRAD_FORMAT_F32};
    g.normal = {texels[first].normal, sizeof(Texel), NRAD_FORMAT_F16};
    g.direction = {texels[first].direction, sizeof(Texel), NRAD_FORMAT_F16};
    g.surfaces = surfaces ? surfaces + first : nullptr;
    g.output = rgba + 4 * first;
    g.outputFormat = NRAD_FORMAT_F16;
    g.outputChannels = 4;
    return g;
}

}  // namespace nrad::bench
