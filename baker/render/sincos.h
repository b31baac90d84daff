// Sine and cosine of a sampling angle for the BSDF's one-vertex code (bsdf.cpp) and its lanes
// (bsdf_lanes.cpp), in plain float arithmetic with no branches, so that a loop over lanes vectorises and both
// give the same bits (both files are compiled without fused multiply-adds). Within 7.5e-8 of the true values for
// |phi| <= 8 (bsdf_test checks it against double precision); the angles sampled are in [-pi/4, 2 pi).
#pragma once

namespace nrad {

#if defined(__GNUC__)
#define NRAD_SINCOS_INLINE inline __attribute__((always_inline))
#else
#define NRAD_SINCOS_INLINE inline
#endif

NRAD_SINCOS_INLINE void sinCos(float phi, float& sine, float& cosine) {
    // phi = k pi/2 + r with |r| <= pi/4: k rounded to nearest by the float magic number (|k| < 2^22), r by
    // Cody and Waite's three-part pi/2 (k * kPiOver2A is exact for |k| < 2^15).
    constexpr float kTwoOverPi = 0.636619772367581343f;
    constexpr float kRound = 12582912.0f;  // 1.5 * 2^23
    constexpr float kPiOver2A = 1.5703125f, kPiOver2B = 4.837512969970703125e-4f, kPiOver2C = 7.54978995489188216e-8f;
    const float k = (phi * kTwoOverPi + kRound) - kRound;
    const float r = ((phi - k * kPiOver2A) - k * kPiOver2B) - k * kPiOver2C;
    // Cephes' minimax polynomials on [-pi/4, pi/4].
    const float z = r * r;
    const float s = ((-1.9515295891e-4f * z + 8.3321608736e-3f) * z - 1.6666654611e-1f) * z * r + r;
    const float c = ((2.443315711809948e-5f * z - 1.388731625493765e-3f) * z + 4.166664568298827e-2f) * z * z -
                    0.5f * z + 1.0f;
    // The quadrant k mod 4 (two's complement: also for negative k) picks and signs them.
    const int q = int(k);
    const float sineBase = (q & 1) != 0 ? c : s;
    const float cosineBase = (q & 1) != 0 ? s : c;
    sine = (q & 2) != 0 ? -sineBase : sineBase;
    cosine = ((q + 1) & 2) != 0 ? -cosineBase : cosineBase;
}

}  // namespace nrad
