// The SIMD evaluation code, written once over a small vector-traits type V that kernel_avx2.cpp and
// kernel_avx512.cpp define. Each of those files includes this header inside its own anonymous namespace
// and compiles it for its own instruction set, so no inline code is shared between translation units
// built with different -m flags (which could let the linker pick an AVX-512 copy for a scalar caller).
// No standard-library templates are used here for the same reason.
//
// V provides: F (vector of W floats), I (vector of W int32), W, and
//   load/store (unaligned), set1, seti, zero, add, sub, mul, div, fmadd(a, b, c) = a b + c, fnmadd = c - a b,
//   select(mask, a, b) (lanes of mask from a, the others from b),
//   min, max (both return the second operand when either is NaN, like the x86 instructions),
//   roundNearest, timesPow2(q, n) = q 2^n for integral n in [-126, 127], cvtTrunc (F -> I), cvtFloat
//   (I -> F), addi, mullo, mini, selecti (as select, of I), gatheri / gatherf (base[index] per lane), storei,
//   firstLane (lane 0 of an I), geMask/leMask (ordered compares)
//   and equalMask (of two F or two I) -> bit mask of W lanes,
//   deinterleave3 / interleave3 (x0 y0 z0 x1 ... <-> three vectors), sqrt, loadHalf (W fp16 values -> F)
//   and storeHalf (F -> W fp16 values, saturated at 65504 as format::floatToHalf does; the input is never NaN);
//   kStridedLoads: whether it has loadStrided3 (three fp32 components of W points `stride` bytes apart, 16
//   bytes read per point) and loadStrided3Half (three fp16 components, 8 bytes read per point);
//   kRgbaStores: whether it has storeHalfRgba and storeRgba (three F as W fp16 or fp32 RGBA pixels of alpha 1,
//   `stride` bytes apart);
//   kSurfaceLoads: whether it has loadSurfaces (W NradSurfaces' nine floats, `stride` bytes apart, as nine F).
//
// The code is in four parts, included here in order: simd_network.h (networks), simd_blend.h (a batch's
// coordinates, blending in registers), simd_gbuffer.h (G-buffers), simd_blocks.h (the block driver).
#include "simd_network.h"
#include "simd_blend.h"
#include "simd_gbuffer.h"
#include "simd_blocks.h"
