// The scattering at many path vertices at once (the batched path tracer) whose next event estimation samples a
// quad light: the rest of the light sample that LightSampler::pickQuad began (TriangleLight::sampleAt from the
// vertex), the BSDF's work (shadeLanes) and what PathTracer::scatterEnd makes of both (the shadow ray and the
// contribution it decides; the throughput, Russian roulette and the extension ray), in structure-of-arrays
// lanes with the scalar code's operations in its order, so its bits (the batched path tracer's images and
// scatter_lanes_test check it). For materials without transmission.
#pragma once

#include <cstddef>

#include "baker/render/bsdf_lanes.h"

namespace nrad {

struct ScatterLanes {
    static constexpr size_t kLanes = BsdfLanes::kLanes;
    // In: the vertex (position, geometric normal on wo's side, its triangle's margin, the path throughput, the
    // Russian roulette's sample point and 1 where the roulette plays at this vertex, else 0),
    // the picked point on the light and its triangle's terms (LightSampler::QuadPick), and in `bsdf` the
    // shading normal, wo, material and sample points (its light direction lx, ly, lz is written here).
    float px[kLanes], py[kLanes], pz[kLanes];
    float ngx[kLanes], ngy[kLanes], ngz[kLanes];
    float margin[kLanes];
    float betaR[kLanes], betaG[kLanes], betaB[kLanes];
    float uRoulette[kLanes], roulette[kLanes];
    float rouletteThreshold = 1.0f;  // PathTracer's
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
    // Out: whether the path goes on (1, else 0) along the BSDF sample, the extension ray's tnear and the new
    // throughput in betaR, betaG, betaB (where it goes on).
    float more[kLanes], extensionTnear[kLanes];
};

// Fills the outputs of lanes [0, n), n <= kLanes.
void scatterLanes(ScatterLanes& lanes, size_t n);

}  // namespace nrad
