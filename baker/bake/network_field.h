// NetworkField: the baker's networks as the runtime would shade with them, in float, while they are still
// being trained: for a surface interaction, the scattered radiance L - Le its cell's networks give towards wo
// (blended and renormalised over cells with networks, multiplied back by the reflectance when demodulated:
// nrad/eval.h's contract without the emission). What stands in for the rest of a path in training within
// the integral equation (PathTracer::scatteredRadiance).
#pragma once

#include <cstdint>
#include <vector>

#include <glm/glm.hpp>
#include <nrad/eval.h>
#include <nrad/format.h>

#include "baker/render/surface.h"

namespace nrad {

class NetworkField {
public:
    NetworkField(const eval::Partition& partition, const format::Topology& topology, format::OutputTransform transform,
                 bool demodulated);

    // Sets (or replaces) the network of `cell`: its parameters in the format's order and its output scale.
    void set(uint32_t cell, const std::vector<float>& params, float scale);
    bool has(uint32_t cell) const { return index_[cell] >= 0; }

    // What the networks hold at p for shading normal n (on the side of wo) and direction wo (unit): the
    // blended network radiance (the asset's value, before the reflectance).
    glm::vec3 assetRadiance(const glm::vec3& p, const glm::vec3& n, const glm::vec3& wo) const;
    // The scattered radiance leaving si towards si.wo: assetRadiance times the reflectance if demodulated.
    glm::vec3 scattered(const SurfaceInteraction& si) const;

private:
    const eval::Partition& partition_;
    format::Topology topology_;
    format::OutputTransform transform_;
    bool demodulated_;
    size_t paramCount_;
    std::vector<int32_t> index_;  // per cell: its network, -1 none
    std::vector<float> params_, scales_;
};

}  // namespace nrad
