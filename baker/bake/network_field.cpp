// The networks being trained, evaluated as the runtime's scalar path does (nrad/eval.h).
#include "baker/bake/network_field.h"

namespace nrad {

NetworkField::NetworkField(const eval::Partition& partition, const format::Topology& topology, format::OutputTransform transform,
                           bool demodulated)
    : partition_(partition), topology_(topology), transform_(transform), demodulated_(demodulated),
      paramCount_(size_t(topology.parameterCount())), index_(size_t(partition.cells), -1) {}

void NetworkField::set(uint32_t cell, const std::vector<float>& params, float scale) {
    if (index_[cell] < 0) {
        index_[cell] = int32_t(scales_.size());
        scales_.push_back(scale);
        params_.resize(params_.size() + paramCount_);
    }
    const size_t k = size_t(index_[cell]);
    scales_[k] = scale;
    std::copy(params.begin(), params.begin() + std::ptrdiff_t(paramCount_), params_.begin() + std::ptrdiff_t(k * paramCount_));
}

glm::vec3 NetworkField::assetRadiance(const glm::vec3& p, const glm::vec3& n, const glm::vec3& wo) const {
    const float pos[3] = {p.x, p.y, p.z}, normal[3] = {n.x, n.y, n.z}, direction[3] = {wo.x, wo.y, wo.z};
    eval::Support sup[eval::kMaxSupports];
    int count = partition_.supports(pos, sup);
    count = eval::keepOccupied(sup, count, [&](int64_t c) { return index_[size_t(c)] >= 0; });
    glm::vec3 L(0.0f);
    float x[eval::kInputs], y[eval::kOutputs], rgb[eval::kOutputs], scratch[eval::kForwardScratch];
    for (int k = 0; k < count; ++k) {
        const size_t net = size_t(index_[size_t(sup[k].voxel)]);
        eval::encodeInputs(sup[k].local, normal, direction, x);
        eval::forward(topology_, &params_[net * paramCount_], x, y, scratch);
        eval::decodeOutputs(transform_, scales_[net], y, rgb);
        L += sup[k].weight * glm::vec3(rgb[0], rgb[1], rgb[2]);
    }
    return L;
}

glm::vec3 NetworkField::scattered(const SurfaceInteraction& si) const {
    glm::vec3 L = assetRadiance(si.p, si.ns, si.wo);
    if (demodulated_) {
        float r[3];
        eval::reflectance(shadingSurface(si), glm::dot(si.ns, si.wo), r);
        L *= glm::vec3(r[0], r[1], r[2]);
    }
    return L;
}

}  // namespace nrad
