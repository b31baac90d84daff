// TriangleLight::sampleAt, the candidate test of PathTracer::scatterBegin and the light half of scatterEnd
// (shadowRay, spawnDistance, rayOffset, the power heuristic) over lanes, branch-free: every expression is the
// scalar code's, operand for operand (glm's dot is (x + y) + z), so the results are its bits; where the
// scalar code returns early, the lanes compute on and select.
#include "baker/render/nee_lanes.h"

#include "baker/render/lane_math.h"

#include <cmath>
#include <limits>

namespace nrad {

namespace {

using namespace lanes;

// rayOffset (accel.cpp)
NRAD_LANE float rayOffset(float x, float y, float z) { return maxOf(maxOf(std::abs(x), maxOf(std::abs(y), std::abs(z))) * 4e-6f, 1e-30f); }

}  // namespace

// x86-64: clones for AVX2 and AVX-512, chosen at load time (NRAD_NO_TARGET_CLONES: the default alone); no fused
// multiply-adds in any (-ffp-contract=off), so all give the same bits.
#if defined(__x86_64__) && defined(__GNUC__) && !defined(__clang__) && !defined(NRAD_NO_TARGET_CLONES)
__attribute__((target_clones("avx512f", "avx2", "default")))
#endif
void neeLanes(NeeLanes& L, size_t n) {
    constexpr float kInf = std::numeric_limits<float>::infinity();
    float dist[NeeLanes::kLanes], pdf[NeeLanes::kLanes], LiR[NeeLanes::kLanes], LiG[NeeLanes::kLanes], LiB[NeeLanes::kLanes];
    float nlx[NeeLanes::kLanes], nly[NeeLanes::kLanes], nlz[NeeLanes::kLanes], candidate[NeeLanes::kLanes];
    BsdfLanes& B = L.bsdf;
    for (size_t k = 0; k < n; ++k) {
        // TriangleLight::sampleAt(p, pl) and the pick probability.
        const float dx = L.plx[k] - L.px[k], dy = L.ply[k] - L.py[k], dz = L.plz[k] - L.pz[k];
        const float dist2 = dx * dx + dy * dy + dz * dz;
        const float d = std::sqrt(dist2);
        const float wx = dx / d, wy = dy / d, wz = dz / d;
        const float cosLight = L.lnx[k] * -wx + L.lny[k] * -wy + L.lnz[k] * -wz;
        const bool front = cosLight > 0.0f;
        nlx[k] = front ? L.lnx[k] : -L.lnx[k];
        nly[k] = front ? L.lny[k] : -L.lny[k];
        nlz[k] = front ? L.lnz[k] : -L.lnz[k];
        const float absCos = std::abs(cosLight);
        float r = front ? L.frontR[k] : L.backR[k], g = front ? L.frontG[k] : L.backG[k], b = front ? L.frontB[k] : L.backB[k];
        float q = dist2 / (absCos * L.area[k]);
        q = finite(q) ? q : 0.0f;
        // sampleAt's early returns (a point at the light, seen edge-on): the empty sample, pdf and radiance zero
        q = absCos > 0.0f ? q : 0.0f;
        q = dist2 > 0.0f ? q : 0.0f;
        r = q > 0.0f ? r : 0.0f;
        g = q > 0.0f ? g : 0.0f;
        b = q > 0.0f ? b : 0.0f;
        q = q * L.pick[k];
        // scatterBegin: a candidate has a positive pdf and radiance and arrives from above the geometric surface
        // (sameSideRule without transmission).
        const float above = wx * L.ngx[k] + wy * L.ngy[k] + wz * L.ngz[k];
        float c = above > 0.0f ? 1.0f : 0.0f;
        c = q > 0.0f ? c : 0.0f;
        // isBlack(Li), one condition at a time (GCC vectorises float selects, not nested or combined ones)
        float black = b <= 0.0f ? 1.0f : 0.0f;
        black = g <= 0.0f ? black : 0.0f;
        black = r <= 0.0f ? black : 0.0f;
        candidate[k] = black > 0.0f ? 0.0f : c;
        dist[k] = d, pdf[k] = q, LiR[k] = r, LiG[k] = g, LiB[k] = b;
        L.wix[k] = wx, L.wiy[k] = wy, L.wiz[k] = wz;
        // shadeBatch: the BSDF is evaluated at the light sample where it is a candidate, else at the normal.
        B.lx[k] = candidate[k] > 0.0f ? wx : B.nx[k];
        B.ly[k] = candidate[k] > 0.0f ? wy : B.ny[k];
        B.lz[k] = candidate[k] > 0.0f ? wz : B.nz[k];
    }
    shadeLanes(B, n);
    for (size_t k = 0; k < n; ++k) {
        const float wx = L.wix[k], wy = L.wiy[k], wz = L.wiz[k];
        // scatterEnd: f = neeEval * |dot(wi, ns)|, a shadow ray where f is not black.
        const float cosS = std::abs(wx * B.nx[k] + wy * B.ny[k] + wz * B.nz[k]);
        const float fr = B.evalR[k] * cosS, fg = B.evalG[k] * cosS, fb = B.evalB[k] * cosS;
        float black = fb <= 0.0f ? 1.0f : 0.0f;
        black = fg <= 0.0f ? black : 0.0f;
        black = fr <= 0.0f ? black : 0.0f;
        L.pending[k] = black > 0.0f ? 0.0f : candidate[k];
        // shadowRay: spawnDistance(wi) at the vertex, the light's end short of it by the larger margin.
        const float offP = rayOffset(L.px[k], L.py[k], L.pz[k]);
        const float cn = std::abs(wx * L.ngx[k] + wy * L.ngy[k] + wz * L.ngz[k]);
        const float tnear = maxOf(L.margin[k], offP) / cn;
        L.tnear[k] = cn > 0.0f ? tnear : kInf;
        const float margin = maxOf(maxOf(L.lightMargin[k], rayOffset(L.plx[k], L.ply[k], L.plz[k])), maxOf(L.margin[k], offP));
        const float cl = std::abs(wx * nlx[k] + wy * nly[k] + wz * nlz[k]);
        const float tfar = dist[k] - margin / cl;
        L.tfar[k] = cl > 0.0f ? tfar : 0.0f;
        // powerHeuristic(pdf, bsdf pdf); the contribution beta * f * Li * (w / pdf).
        const float f2 = pdf[k] * pdf[k], g2 = B.evalPdf[k] * B.evalPdf[k];
        const float sum = f2 + g2;
        float w = f2 / sum;
        w = sum > 0.0f ? w : 0.0f;
        w = std::abs(f2) == kInf ? 1.0f : w;
        const float s = w / pdf[k];
        L.contribR[k] = L.betaR[k] * fr * LiR[k] * s;
        L.contribG[k] = L.betaG[k] * fg * LiG[k] * s;
        L.contribB[k] = L.betaB[k] * fb * LiB[k] * s;
    }
}

}  // namespace nrad
