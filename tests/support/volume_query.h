// The volume query of an asset (nrad/eval.h's contract read with the baker's NetworkField): what the tests of the
// light in the volume hold the bake and the runtime to.
#pragma once

#include <vector>

#include <glm/glm.hpp>
#include <nrad/eval.h>
#include <nrad/format.h>

#include "baker/bake/network_field.h"

namespace nrad::test {

// The volume networks of `a` (its weights as decoded or as baked) at (p, n): E(x, n) / pi; with `glossy` its glossy
// response's at (p, n, v).
class VolumeQuery {
public:
    explicit VolumeQuery(const format::Asset& a, bool glossy = false)
        : partition_(a), field_(partition_, a.topology, glossy ? a.topology.outputTransform : a.volumeTransform(), false) {
        const size_t per = a.topology.parameterCount();
        const std::vector<format::VoxelEntry>& voxels = glossy ? a.glossyVoxels : a.volumeVoxels;
        const std::vector<float>& weights = glossy ? a.glossyWeights : a.volumeWeights;
        for (size_t k = 0; k < voxels.size(); ++k) {
            field_.set(voxels[k].index, std::vector<float>(weights.begin() + ptrdiff_t(k * per), weights.begin() + ptrdiff_t((k + 1) * per)),
                       voxels[k].scale);
            largestScale_ = std::max(largestScale_, voxels[k].scale);
        }
    }
    glm::vec3 operator()(const glm::vec3& p, const glm::vec3& n) const { return field_.assetRadiance(p, n, n); }
    glm::vec3 operator()(const glm::vec3& p, const glm::vec3& n, const glm::vec3& v) const { return field_.assetRadiance(p, n, v); }
    float largestScale() const { return largestScale_; }

private:
    eval::Partition partition_;
    NetworkField field_;
    float largestScale_ = 0.0f;
};

}  // namespace nrad::test
