// Shading and G-buffers: the shading contract applied to what the asset returns, and nradShadeGBuffer's
// tiles (conversion from the caller's attributes, evaluation, shading, the output's format and stride).
#pragma once

#include <nrad/nrad.h>

namespace nrad::rt {

// A G-buffer, tile by tile, in `scratch` (nradGetScratchSize() bytes); its arguments already checked.
void shadeGBuffer(const NradAsset_& a, const NradGBuffer& g, void* scratch);

}  // namespace nrad::rt
