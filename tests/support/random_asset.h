// A random asset for runtime tests: networks of the given hidden widths on every other voxel of a grid over
// [-1, 2] x [-2, 3] x [-3, 4], weights uniform in [-0.6, 0.6] (rounded to fp16 when encoded so), scales
// 0.5 + the voxel's index, optionally blended.
#pragma once

#include <random>
#include <vector>

#include <glm/glm.hpp>
#include <nrad/format.h>

namespace nrad::test {

inline format::Asset randomAsset(std::vector<uint32_t> hidden, format::WeightEncoding enc, format::OutputTransform transform,
                                 uint32_t seed, glm::uvec3 dims = glm::uvec3(3, 2, 2), float band = 0.0f) {
    std::mt19937 rng(seed);
    std::uniform_real_distribution<float> u(-1.0f, 1.0f);
    format::Asset a;
    if (band > 0.0f) {
        a.header.flags = format::kFlagBlended;
        a.grid.blendBand = band;
    }
    for (int k = 0; k < 3; ++k) {
        a.grid.lower[k] = -1.0f - float(k);
        a.grid.upper[k] = 2.0f + float(k);
        a.grid.dims[k] = dims[k];
    }
    a.topology.hiddenWidths = hidden;
    a.topology.weightEncoding = enc;
    a.topology.outputTransform = transform;
    for (uint32_t v = 0; v < a.grid.voxelCount(); v += 2) a.voxels.push_back({v, 0.5f + float(v)});  // every other voxel
    size_t n = a.voxels.size() * a.topology.parameterCount();
    for (size_t i = 0; i < n; ++i) {
        float w = 0.6f * u(rng);
        a.weights.push_back(enc == format::WeightEncoding::Float16 ? format::halfToFloat(format::floatToHalf(w)) : w);
    }
    a.metadata = "{\"test\":true}";
    return a;
}

}  // namespace nrad::test
