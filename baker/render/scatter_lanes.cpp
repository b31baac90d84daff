// TriangleLight::sampleAt, the candidate test of PathTracer::scatterBegin and scatterEnd (shadowRay,
// spawnDistance, rayOffset, the power heuristic; extend's throughput and roulette) over lanes, branch-free: every expression is the
// scalar code's, operand for operand (glm's dot is (x + y) + z), so the results are its bits; where the
// scalar code returns early, the lanes compute on and select.
#include "baker/render/scatter_lanes.h"

#include "baker/render/lane_math.h"

#include <cmath>
#include <limits>

namespace nrad {

namespace {

using namespace lanes;

// isBlack (path_tracer.cpp): 1 where no component is positive, else 0; one condition at a time (GCC vectorises
// float selects, not nested or combined ones).
NRAD_LANE float black(float r, float g, float b) {
    float black = b <= 0.0f ? 1.0f : 0.0f;
    black = g <= 0.0f ? black : 0.0f;
    return r <= 0.0f ? black : 0.0f;
}

// rayOffset (accel.cpp)
NRAD_LANE float rayOffset(float x, float y, float z) { return maxOf(maxOf(std::abs(x), maxOf(std::abs(y), std::abs(z))) * 4e-6f, 1e-30f); }

}  // namespace

// x86-64: clones for AVX2 and AVX-512, chosen at load time (NRAD_NO_TARGET_CLONES: the default alone); no fused
// multiply-adds in any (-ffp-contract=off), so all give the same bits.
#if defined(__x86_64__) && defined(__GNUC__) && !defined(__clang__) && !defined(NRAD_NO_TARGET_CLONES)
__attribute__((target_clones("avx512f", "avx2", "default")))
#endif
void scatterLanes(ScatterLanes& L, size_t n) {
    constexpr float kInf = std::numeric_limits<float>::infinity();
    float dist[ScatterLanes::kLanes], pdf[ScatterLanes::kLanes], LiR[ScatterLanes::kLanes], LiG[ScatterLanes::kLanes], LiB[ScatterLanes::kLanes];
    float nlx[ScatterLanes::kLanes], nly[ScatterLanes::kLanes], nlz[ScatterLanes::kLanes], candidate[ScatterLanes::kLanes];
    float offsetP[ScatterLanes::kLanes];  // rayOffset of the vertex, for both rays' tnear
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
        candidate[k] = black(r, g, b) > 0.0f ? 0.0f : c;
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
        L.pending[k] = black(fr, fg, fb) > 0.0f ? 0.0f : candidate[k];
        // shadowRay: spawnDistance(wi) at the vertex, the light's end short of it by the larger margin.
        const float offP = offsetP[k] = rayOffset(L.px[k], L.py[k], L.pz[k]);
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
    for (size_t k = 0; k < n; ++k) {
        // extend: a valid sample above the geometric surface; the throughput times f |cos| / pdf, neither black
        // nor infinite; Russian roulette; the extension ray from the vertex.
        const float ix = B.sampleX[k], iy = B.sampleY[k], iz = B.sampleZ[k], pdfS = B.samplePdf[k];
        const float cs = std::abs(ix * B.nx[k] + iy * B.ny[k] + iz * B.nz[k]) / pdfS;
        float r = L.betaR[k] * (B.sampleR[k] * cs), g = L.betaG[k] * (B.sampleG[k] * cs), b = L.betaB[k] * (B.sampleB[k] * cs);
        const float above = ix * L.ngx[k] + iy * L.ngy[k] + iz * L.ngz[k];
        float more = above > 0.0f ? 1.0f : 0.0f;
        more = pdfS > 0.0f ? more : 0.0f;
        more = black(r, g, b) > 0.0f ? 0.0f : more;
        more = finite(r) ? more : 0.0f;
        more = finite(g) ? more : 0.0f;
        more = finite(b) ? more : 0.0f;
        const float q = minOf(1.0f, maxOf(r, maxOf(g, b)) / L.rouletteThreshold);
        const float survives = L.uRoulette[k] >= q ? 0.0f : 1.0f;
        const bool plays = L.roulette[k] > 0.0f;
        more = plays ? (survives > 0.0f ? more : 0.0f) : more;
        r = plays ? r / q : r;
        g = plays ? g / q : g;
        b = plays ? b / q : b;
        L.more[k] = more;
        L.betaR[k] = r, L.betaG[k] = g, L.betaB[k] = b;
        const float cn = std::abs(above);
        const float tnear = maxOf(L.margin[k], offsetP[k]) / cn;
        L.extensionTnear[k] = cn > 0.0f ? tnear : kInf;
    }
}

}  // namespace nrad
