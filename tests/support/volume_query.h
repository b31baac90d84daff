// The volume query of an asset (nrad/eval.h's contract read with the baker's NetworkField): what the tests of the
// light in the volume hold the bake and the runtime to.
#pragma once

#include <vector>

#include <glm/glm.hpp>
#include <nrad/eval.h>
#include <nrad/format.h>

#include "baker/bake/network_field.h"

namespace nrad::test {

// The volume networks of `a` (its weights as decoded or as baked) at (p, n): E(x, n) / pi.
class VolumeQuery {
public:
    explicit VolumeQuery(const format::Asset& a)
        : partition_(a), field_(partition_, a.topology, a.topology.outputTransform, false) {
        const size_t per = a.topology.parameterCount();
        for (size_t k = 0; k < a.volumeVoxels.size(); ++k) {
            field_.set(a.volumeVoxels[k].index, std::vector<float>(a.volumeWeights.begin() + ptrdiff_t(k * per),
                                                                   a.volumeWeights.begin() + ptrdiff_t((k + 1) * per)),
                       a.volumeVoxels[k].scale);
            largestScale_ = std::max(largestScale_, a.volumeVoxels[k].scale);
        }
    }
    glm::vec3 operator()(const glm::vec3& p, const glm::vec3& n) const { return field_.assetRadiance(p, n, n); }
    float largestScale() const { return largestScale_; }

private:
    eval::Partition partition_;
    NetworkField field_;
    float largestScale_ = 0.0f;
};

}  // namespace nrad::test
