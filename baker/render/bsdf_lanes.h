// The BSDF's work at many path vertices at once (the batched path tracer): what Bsdf(Frame::fromNormal(ns),
// params), outgoing(wo), eval and pdf at a light sample's direction and sample(uLobe, u) compute, in
// structure-of-arrays lanes and branch-free loops the compiler vectorises, with the same operations in the
// same order, so the same bits (bsdf_test and the batched path tracer's images check it). For materials
// without transmission (transmission == 0); the path tracer shades the others one at a time.
#pragma once

#include <cstddef>

namespace nrad {

struct BsdfLanes {
    static constexpr size_t kLanes = 64;
    // In: the shading normal, wo and the light sample's direction (world space, unit), the material, the
    // lobe choice and the 2D sample point of the BSDF sample.
    float nx[kLanes], ny[kLanes], nz[kLanes];
    float wox[kLanes], woy[kLanes], woz[kLanes];
    float lx[kLanes], ly[kLanes], lz[kLanes];
    float baseR[kLanes], baseG[kLanes], baseB[kLanes];
    float metallic[kLanes], roughness[kLanes], specular[kLanes];
    float specR[kLanes], specG[kLanes], specB[kLanes];
    float ior[kLanes];
    float uLobe[kLanes], u0[kLanes], u1[kLanes];
    // Out: eval (without the cosine) and pdf at the light direction; the BSDF sample (pdf 0 where none, then
    // its direction and value are zero).
    float evalR[kLanes], evalG[kLanes], evalB[kLanes], evalPdf[kLanes];
    float sampleX[kLanes], sampleY[kLanes], sampleZ[kLanes];
    float sampleR[kLanes], sampleG[kLanes], sampleB[kLanes], samplePdf[kLanes];
};

// Fills the outputs of lanes [0, n), n <= kLanes.
void shadeLanes(BsdfLanes& lanes, size_t n);

}  // namespace nrad
