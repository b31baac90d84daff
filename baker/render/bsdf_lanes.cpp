// Bsdf's arithmetic (bsdf.cpp, glm's dot, normalize, cross and reflect) over lanes, branch-free: every
// expression is the scalar code's, operand for operand, so the results are its bits; where the scalar code
// returns early, the lanes compute on and select. The sine and cosine are sincos.h's, shared with the scalar code.
#include "baker/render/bsdf_lanes.h"

#include <cfloat>
#include <cmath>

#include "baker/render/bsdf.h"
#include "baker/render/lane_math.h"
#include "baker/render/sincos.h"
#include "baker/util/maths.h"

namespace nrad {

namespace {


#define LANE NRAD_LANE
using namespace lanes;

LANE float pow5(float x) {
    float x2 = x * x;
    return x2 * x2 * x;
}
// Selects are written one condition at a time, on floats: GCC vectorises those, not nested or combined
// boolean ones.

// Bsdf::ggxD at the unnormalised half vector (hx, hy, hz).
LANE float ggxD(float hx, float hy, float hz, float alpha) {
    float a2 = alpha * alpha;
    float t2 = hx * hx + hy * hy;
    float z2 = hz * hz;
    float d = (t2 + a2 * z2) / (t2 + z2);
    float D = a2 / (kPi * d * d);
    return hz <= 0.0f ? 0.0f : D;
}

LANE float ggxLambda(float cosTheta, float alpha) {
    float c2 = cosTheta * cosTheta;
    float tan2 = maxOf(0.0f, 1.0f - c2) / c2;
    float lambda = 0.5f * (std::sqrt(1.0f + alpha * alpha * tan2) - 1.0f);
    return c2 <= 0.0f ? 0.0f : lambda;
}

// One lane's vertex: what Bsdf's constructor and outgoing() keep.
struct Vertex {
    float sx, sy, sz, tx, ty, tz, nx, ny, nz;  // Frame
    float wx, wy, wz;  // wo, local
    float alpha, f0r, f0g, f0b;
    float lambda, fresnel, pSpec;  // pTrans is 0 without transmission
    float baseR, baseG, baseB, metallic, specular;
};

LANE float macroFresnel(const Vertex& v, float cosTheta) {
    float p = pow5(1.0f - cosTheta);
    float r = v.f0r + (1.0f - v.f0r) * p, g = v.f0g + (1.0f - v.f0g) * p, b = v.f0b + (1.0f - v.f0b) * p;
    return maxOf(r, maxOf(g, b));
}

LANE Vertex vertex(const BsdfLanes& L, size_t k) {
    Vertex v;
    // Frame::fromNormal
    const float nx = L.nx[k], ny = L.ny[k], nz = L.nz[k];
    const float sign = std::copysign(1.0f, nz);
    const float a = -1.0f / (sign + nz);
    const float b = nx * ny * a;
    v.sx = 1.0f + sign * nx * nx * a;
    v.sy = sign * b;
    v.sz = -sign * nx;
    v.tx = b;
    v.ty = sign + ny * ny * a;
    v.tz = -ny;
    v.nx = nx;
    v.ny = ny;
    v.nz = nz;
    // Bsdf::Bsdf
    v.alpha = maxOf(L.roughness[k] * L.roughness[k], Bsdf::kMinAlpha);
    const float f0 = (L.ior[k] - 1.0f) / (L.ior[k] + 1.0f);
    v.f0r = minOf(f0 * f0 * L.specR[k], 1.0f);
    v.f0g = minOf(f0 * f0 * L.specG[k], 1.0f);
    v.f0b = minOf(f0 * f0 * L.specB[k], 1.0f);
    v.baseR = L.baseR[k];
    v.baseG = L.baseG[k];
    v.baseB = L.baseB[k];
    v.metallic = L.metallic[k];
    v.specular = L.specular[k];
    // Bsdf::outgoing
    const float wx = L.wox[k], wy = L.woy[k], wz = L.woz[k];
    v.wx = wx * v.sx + wy * v.sy + wz * v.sz;
    v.wy = wx * v.tx + wy * v.ty + wz * v.tz;
    v.wz = wx * v.nx + wy * v.ny + wz * v.nz;
    v.lambda = ggxLambda(v.wz, v.alpha);
    v.fresnel = macroFresnel(v, v.wz);
    // lobeWeights and lobeProbabilities with transmission 0 (its terms drop out exactly: (1 - 0) base is base,
    // the transmission weight 0 base is 0 for the finite base here, and x - 0 is x)
    const float baseLum = 0.2126f * v.baseR + 0.7152f * v.baseG + 0.0722f * v.baseB;
    const float spec = v.metallic + (1.0f - v.metallic) * v.specular * v.fresnel;
    const float base = (1.0f - v.metallic) * (1.0f - v.specular * v.fresnel) * baseLum;
    const float sum = spec + base;
    const float ratio = spec / sum;
    const float pSpec = sum > spec ? ratio : 1.0f;
    v.pSpec = spec <= 0.0f ? 0.0f : pSpec;
    return v;
}

// Bsdf::evalLocal for wi on wo's side (or zero), into r, g, b.
LANE void evalLocal(const Vertex& v, float ix, float iy, float iz, float& r, float& g, float& b) {
    const float sx = v.wx + ix, sy = v.wy + iy, sz = v.wz + iz;
    const float hl = std::sqrt(sx * sx + sy * sy + sz * sz);
    const float hx = sx / hl, hy = sy / hl, hz = sz / hl;
    const float vdoth = clamp01(v.wx * hx + v.wy * hy + v.wz * hz);
    const float schlick = pow5(1.0f - vdoth);
    const float g2 = 1.0f / (1.0f + v.lambda + ggxLambda(iz, v.alpha));
    const float spec = ggxD(sx, sy, sz, v.alpha) * g2 / (4.0f * v.wz * iz);
    const float transmitted = (1.0f - v.specular * v.fresnel) * (1.0f - v.specular * macroFresnel(v, iz));
    const float m = v.metallic, s = v.specular;
    auto channel = [&](float base, float f0) {
        const float diffuse = base / kPi;
        const float fr = f0 + (1.0f - f0) * schlick;
        const float dielectric = transmitted * diffuse + s * fr * spec;
        const float metal = (base + (1.0f - base) * schlick) * spec;
        float c = (1.0f - m) * dielectric + m * metal;
        // evalLocal's early returns: wo below, wi in the plane or below (no transmission), h of no length
        c = v.wz <= 0.0f ? 0.0f : c;
        c = iz == 0.0f ? 0.0f : c;
        c = iz < 0.0f ? 0.0f : c;
        return hl > 0.0f ? c : 0.0f;
    };
    r = channel(v.baseR, v.f0r);
    g = channel(v.baseG, v.f0g);
    b = channel(v.baseB, v.f0b);
}

// Bsdf::pdfLocal for wi on wo's side (or zero).
LANE float pdfLocal(const Vertex& v, float ix, float iy, float iz) {
    float pdf = (1.0f - v.pSpec) * iz / kPi;
    // glm::normalize(wo + wi): times the inverse square root of its squared length
    const float hx0 = v.wx + ix, hy0 = v.wy + iy, hz0 = v.wz + iz;
    const float inv = 1.0f / std::sqrt(hx0 * hx0 + hy0 * hy0 + hz0 * hz0);
    const float hx = hx0 * inv, hy = hy0 * inv, hz = hz0 * inv;
    const float odoth = v.wx * hx + v.wy * hy + v.wz * hz;
    const float g1 = 1.0f / (1.0f + v.lambda);
    const float withSpec = pdf + v.pSpec * g1 * ggxD(hx0, hy0, hz0, v.alpha) / (4.0f * v.wz);
    const float spec = odoth > 0.0f ? withSpec : pdf;
    pdf = v.pSpec > 0.0f ? spec : pdf;
    pdf = v.wz <= 0.0f ? 0.0f : pdf;
    pdf = iz == 0.0f ? 0.0f : pdf;
    return iz < 0.0f ? 0.0f : pdf;
}

}  // namespace

// x86-64: clones for AVX2 and AVX-512 (8 and 16 lanes), chosen at load time (NRAD_NO_TARGET_CLONES: the
// default alone, for its test); no fused multiply-adds in any (-ffp-contract=off), so all give the same bits.
#if defined(__x86_64__) && defined(__GNUC__) && !defined(__clang__) && !defined(NRAD_NO_TARGET_CLONES)
__attribute__((target_clones("avx512f", "avx2", "default")))
#endif
void shadeLanes(BsdfLanes& L, size_t n) {
    float r[BsdfLanes::kLanes], phi[BsdfLanes::kLanes], cosPhi[BsdfLanes::kLanes], sinPhi[BsdfLanes::kLanes];
    // The light sample: eval and pdf at its direction, and the first half of the BSDF sample (the disk
    // radius and angle of the lobe chosen).
    for (size_t k = 0; k < n; ++k) {
        const Vertex v = vertex(L, k);
        const float ix = L.lx[k] * v.sx + L.ly[k] * v.sy + L.lz[k] * v.sz;
        const float iy = L.lx[k] * v.tx + L.ly[k] * v.ty + L.lz[k] * v.tz;
        const float iz = L.lx[k] * v.nx + L.ly[k] * v.ny + L.lz[k] * v.nz;
        evalLocal(v, ix, iy, iz, L.evalR[k], L.evalG[k], L.evalB[k]);
        L.evalPdf[k] = pdfLocal(v, ix, iy, iz);
        // The specular lobe (sampleVisibleNormal) or the diffuse one (concentric disk mapping).
        const float dx = 2.0f * L.u0[k] - 1.0f, dy = 2.0f * L.u1[k] - 1.0f;
        const bool wide = std::abs(dx) > std::abs(dy);
        float diskR = wide ? dx : dy;
        const float phiWide = (kPi / 4.0f) * (dy / dx), phiTall = (kPi / 2.0f) - (kPi / 4.0f) * (dx / dy);
        float diskPhi = wide ? phiWide : phiTall;
        // the centre: r = phi = 0
        const float centreR = dy == 0.0f ? 0.0f : diskR, centrePhi = dy == 0.0f ? 0.0f : diskPhi;
        diskR = dx == 0.0f ? centreR : diskR;
        diskPhi = dx == 0.0f ? centrePhi : diskPhi;
        const float specR = std::sqrt(L.u0[k]), specPhi = 2.0f * kPi * L.u1[k];
        const bool specular = L.uLobe[k] < v.pSpec;
        r[k] = specular ? specR : diskR;
        phi[k] = specular ? specPhi : diskPhi;
    }
    for (size_t k = 0; k < n; ++k) sinCos(phi[k], sinPhi[k], cosPhi[k]);
    for (size_t k = 0; k < n; ++k) {
        const Vertex v = vertex(L, k);
        const float p1 = r[k] * cosPhi[k], p2r = r[k] * sinPhi[k];
        // Diffuse: the cosine-weighted direction.
        const float dz = std::sqrt(maxOf(0.0f, 1.0f - p1 * p1 - p2r * p2r));
        // Specular: the visible normal, and wo reflected about it.
        const float ax = v.alpha * v.wx, ay = v.alpha * v.wy, az = v.wz;
        const float vinv = 1.0f / std::sqrt(ax * ax + ay * ay + az * az);
        const float vhx = ax * vinv, vhy = ay * vinv, vhz = az * vinv;
        const float lensq = vhx * vhx + vhy * vhy;
        const float sq = std::sqrt(lensq);
        const float q1x = -vhy / sq, q1y = vhx / sq, q1z = 0.0f / sq;
        const float t1x = lensq > 0.0f ? q1x : 1.0f;
        const float t1y = lensq > 0.0f ? q1y : 0.0f;
        const float t1z = lensq > 0.0f ? q1z : 0.0f;
        const float t2x = vhy * t1z - t1y * vhz, t2y = vhz * t1x - t1z * vhx, t2z = vhx * t1y - t1x * vhy;
        const float s = 0.5f * (1.0f + vhz);
        const float p2 = (1.0f - s) * std::sqrt(maxOf(0.0f, 1.0f - p1 * p1)) + s * p2r;
        const float q = std::sqrt(maxOf(0.0f, 1.0f - p1 * p1 - p2 * p2));
        const float nhx = p1 * t1x + p2 * t2x + q * vhx, nhy = p1 * t1y + p2 * t2y + q * vhy, nhz = p1 * t1z + p2 * t2z + q * vhz;
        const float mx = v.alpha * nhx, my = v.alpha * nhy, mz = maxOf(1e-7f, nhz);
        const float minv = 1.0f / std::sqrt(mx * mx + my * my + mz * mz);
        const float hx = mx * minv, hy = my * minv, hz = mz * minv;
        // glm::reflect(-wo, h) = -wo - h * dot(h, -wo) * 2
        const float ix0 = -v.wx, iy0 = -v.wy, iz0 = -v.wz;
        const float d = hx * ix0 + hy * iy0 + hz * iz0;
        const float rx = ix0 - hx * d * 2.0f, ry = iy0 - hy * d * 2.0f, rz = iz0 - hz * d * 2.0f;
        const bool specular = L.uLobe[k] < v.pSpec;
        const float ix = specular ? rx : p1, iy = specular ? ry : p2r, iz = specular ? rz : dz;
        const float pdf = pdfLocal(v, ix, iy, iz);
        // Bsdf::sample's early returns: wo below, wi below, a pdf not positive and finite
        float validPdf = v.wz <= 0.0f ? 0.0f : pdf;
        validPdf = iz <= 0.0f ? 0.0f : validPdf;
        validPdf = finite(pdf) ? validPdf : 0.0f;
        const bool valid = validPdf > 0.0f;
        float fr, fg, fb;
        evalLocal(v, ix, iy, iz, fr, fg, fb);
        L.samplePdf[k] = valid ? pdf : 0.0f;
        L.sampleR[k] = valid ? fr : 0.0f;
        L.sampleG[k] = valid ? fg : 0.0f;
        L.sampleB[k] = valid ? fb : 0.0f;
        // Frame::toWorld: s * x + t * y + n * z
        L.sampleX[k] = valid ? v.sx * ix + v.tx * iy + v.nx * iz : 0.0f;
        L.sampleY[k] = valid ? v.sy * ix + v.ty * iy + v.ny * iz : 0.0f;
        L.sampleZ[k] = valid ? v.sz * ix + v.tz * iy + v.nz * iz : 0.0f;
    }
}

}  // namespace nrad
