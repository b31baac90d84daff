// Next event estimation towards quad lights at many path vertices at once (the batched path tracer): the
// rest of a light sample that LightSampler::pickQuad began (TriangleLight::sampleAt from the vertex), the
// BSDF's work (shadeLanes) and what PathTracer::scatterEnd makes of it (the shadow ray and the contribution
// it decides), in structure-of-arrays lanes with the scalar code's operations in its order, so its bits
// (the batched path tracer's images and nee_lanes_test check it). For materials without transmission.
#pragma once

#include <cstddef>

#include "baker/render/bsdf_lanes.h"

namespace nrad {

struct NeeLanes {
    static constexpr size_t kLanes = BsdfLanes::kLanes;
    // In: the vertex (position, geometric normal on wo's side, its triangle's margin, the path throughput),
    // the picked point on the light and its triangle's terms (LightSampler::QuadPick), and in `bsdf` the
    // shading normal, wo, material and sample points (its light direction lx, ly, lz is written here).
    float px[kLanes], py[kLanes], pz[kLanes];
    float ngx[kLanes], ngy[kLanes], ngz[kLanes];
    float margin[kLanes];
    float betaR[kLanes], betaG[kLanes], betaB[kLanes];
    float plx[kLanes], ply[kLanes], plz[kLanes];
    float lnx[kLanes], lny[kLanes], lnz[kLanes];
    float frontR[kLanes], frontG[kLanes], frontB[kLanes];
    float backR[kLanes], backG[kLanes], backB[kLanes];
    float area[kLanes], lightMargin[kLanes], pick[kLanes];
    BsdfLanes bsdf;
    // Out: whether a shadow ray is to be traced (scatterEnd's shadowPending: 1, else 0), then its direction,
    // extent and the contribution it decides if unblocked; the BSDF sample in `bsdf`.
    float pending[kLanes];
    float wix[kLanes], wiy[kLanes], wiz[kLanes];
    float tnear[kLanes], tfar[kLanes];
    float contribR[kLanes], contribG[kLanes], contribB[kLanes];
};

// Fills the outputs of lanes [0, n), n <= kLanes.
void neeLanes(NeeLanes& lanes, size_t n);

}  // namespace nrad
