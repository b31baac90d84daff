// Shading and G-buffers: the shading contract applied to what the asset returns, and nradShadeGBuffer's
// tiles (conversion from the caller's attributes, evaluation, shading, the output's format and stride).
#include "gbuffer.h"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <limits>

#include "asset.h"
#include "evaluation.h"
#include "kernel_dispatch.h"

namespace nrad::rt {
namespace {

// The final radiance of one point from what the asset returned there (nradShadeBatch's contract; for the volume
// query, eval::shadeVolume's).
void shadeOne(const NradAsset_& a, bool volume, const NradSurface& in, const float n[3], const float d[3], float rgb[3]) {
    eval::Surface s;
    for (int c = 0; c < 3; ++c) {
        s.baseColor[c] = in.baseColor[c];
        s.emission[c] = std::isfinite(in.emission[c]) ? in.emission[c] : 0.0f;
    }
    s.metallic = in.metallic;
    s.roughness = in.roughness;
    s.specular = in.specular;
    const float cosNV = n[0] * d[0] + n[1] * d[1] + n[2] * d[2];
    float out[3];
    if (volume) eval::shadeVolume(rgb, s, std::isfinite(cosNV) ? cosNV : 0.0f, out);
    else eval::shade(a.asset.header.flags, rgb, s, std::isfinite(cosNV) ? cosNV : 0.0f, out);
    for (int c = 0; c < 3; ++c) rgb[c] = std::isfinite(out[c]) ? out[c] : 0.0f;
}

// v / |v|, or NaN (an invalid input) where v is zero or not finite.
void normalise(float v[3]) {
    const float len2 = v[0] * v[0] + v[1] * v[1] + v[2] * v[2];
    if (len2 > 0.0f && std::isfinite(len2)) {
        const float inv = 1.0f / std::sqrt(len2);
        for (int k = 0; k < 3; ++k) v[k] *= inv;
    } else {
        v[0] = v[1] = v[2] = std::numeric_limits<float>::quiet_NaN();
    }
}

// Points [first, first + n) of an attribute into 3 n floats (`staging`: 3 n halves of room).
void gather(const NradAttribute& at, size_t first, size_t n, float* out, uint16_t* staging, const HalfConverters& conv) {
    const bool half = at.format == NRAD_FORMAT_F16;
    const size_t size = half ? 6 : 12, stride = at.stride ? at.stride : size;
    const uint8_t* src = static_cast<const uint8_t*>(at.data) + first * stride;
    void* dst = half ? static_cast<void*>(staging) : static_cast<void*>(out);
    auto* d = static_cast<uint8_t*>(dst);
    if (stride == size)
        std::memcpy(dst, src, n * size);
    else if (half)  // constant sizes: the copies become plain moves
        for (size_t j = 0; j < n; ++j) std::memcpy(d + j * 6, src + j * stride, 6);
    else
        for (size_t j = 0; j < n; ++j) std::memcpy(d + j * 12, src + j * stride, 12);
    if (half) conv.toFloat(staging, out, 3 * n);
}

// n pixels of `size` bytes from `packed` to `out`, `stride` bytes apart.
template <size_t kSize>
void scatterPixels(const uint8_t* packed, uint8_t* out, size_t stride, size_t n) {
    for (size_t j = 0; j < n; ++j) std::memcpy(out + j * stride, packed + j * kSize, kSize);
}

StridedAttribute stridedOf(const NradAttribute& at, size_t first) {
    const bool half = at.format == NRAD_FORMAT_F16;
    const size_t stride = at.stride ? at.stride : (half ? 6 : 12);
    return {static_cast<const uint8_t*>(at.data) + first * stride, stride, half};
}

}  // namespace

// A G-buffer, tile by tile. Where the asset has a block driver, the driver reads each whole vector of texels
// straight from the caller's attributes (GBufferIo), shades and writes its pixels; the rest of a tile (the
// last partial vector, and the points the driver leaves to the other paths, which it converts into the tile's
// fp32 arrays) is gathered, evaluated, shaded and written here. Either way a point gets the same bits.
void shadeGBuffer(const NradAsset_& a, const NradGBuffer& g, void* scratch) {
    Scratch s = carveScratch(scratch);
    auto tileAt = (reinterpret_cast<uintptr_t>(scratch) + kScratchBytes + 63) & ~uintptr_t(63);
    GBufferTile& t = *reinterpret_cast<GBufferTile*>(tileAt);
    const HalfConverters conv = halfConverters(kernelOf(a));
    const bool eye = (g.flags & NRAD_GBUFFER_EYE) != 0, unit = (g.flags & NRAD_GBUFFER_UNIT_VECTORS) != 0;
    // The volume query: its own networks, the normal as their direction input; the viewer's direction (if any)
    // only shades. Through the gather path (the block drivers read one direction for both).
    const bool volume = (g.flags & NRAD_GBUFFER_VOLUME) != 0;
    const bool directions = eye || !volume || g.surfaces;
    const NradAsset_& net = volume ? *a.volume : a;
    const bool half = g.outputFormat == NRAD_FORMAT_F16;
    const size_t channels = g.outputChannels, pixel = channels * (half ? 2 : 4);
    const size_t outStride = g.outputStride ? g.outputStride : pixel;
    const size_t surfaceStride = g.surfaceStride ? g.surfaceStride : sizeof(NradSurface);
    int width = 0;
    const bool fused = !volume && blockDriverOf(a, width) != nullptr;
    for (size_t first = 0; first < g.count; first += kTilePoints) {
        const size_t n = std::min(kTilePoints, g.count - first);
        // The points the block driver will not read: all of them without one, else the last partial vector.
        const size_t from = fused ? n / size_t(width) * size_t(width) : 0;
        gather(g.position, first + from, n - from, t.p + 3 * from, t.halves, conv);
        gather(g.normal, first + from, n - from, t.n + 3 * from, t.halves, conv);
        if (!eye && directions) gather(g.direction, first + from, n - from, t.d + 3 * from, t.halves, conv);
        if (eye || !unit)
            for (size_t j = from; j < n; ++j) {
                float* d = t.d + 3 * j;
                if (eye)
                    for (int k = 0; k < 3; ++k) d[k] = g.eye[k] - t.p[3 * j + size_t(k)];
                if (directions) normalise(d);
                if (!unit) normalise(t.n + 3 * j);
            }
        GBufferIo io{};
        if (fused) {
            io.p = stridedOf(g.position, first);
            io.n = stridedOf(g.normal, first);
            if (!eye) io.d = stridedOf(g.direction, first);
            io.eye = eye;
            for (int k = 0; k < 3; ++k) io.eyePosition[k] = g.eye[k];
            io.normaliseNormals = !unit;
            io.normaliseDirections = eye || !unit;
            // Points whose wide reads (4 bytes past an fp32 point, 2 past an fp16 one) stay inside the attributes:
            // all but the G-buffer's last (its last few with strides under 4 bytes: overlapping attributes).
            auto unsafeTail = [](const StridedAttribute& at) {
                const size_t extra = at.half ? 2 : 4;
                return (extra + at.stride - 1) / at.stride;
            };
            const size_t tail = std::max({unsafeTail(io.p), unsafeTail(io.n), eye ? size_t(0) : unsafeTail(io.d)});
            const size_t safeEnd = g.count > tail ? g.count - tail : 0;
            io.safePoints = safeEnd > first ? std::min(n, safeEnd - first) : 0;
            io.out = static_cast<uint8_t*>(g.output) + first * outStride;
            io.outStride = outStride;
            io.outHalf = half;
            io.channels = int(channels);
            io.done = t.done;
            std::memset(t.done, 0, n);
            if (g.surfaces) {
                io.surfaces = reinterpret_cast<const uint8_t*>(g.surfaces) + first * surfaceStride;
                io.surfaceStride = surfaceStride;
                io.contentFlags = a.asset.header.flags;
            }
        }
        const float* dirs = volume ? t.n : t.d;
        const BatchIo v{{t.p, t.p + 1, t.p + 2}, {t.n, t.n + 1, t.n + 2}, {dirs, dirs + 1, dirs + 2},
                            {t.rgb, t.rgb + 1, t.rgb + 2}, 3, g.pointFlags ? g.pointFlags + first : nullptr,
                            fused ? &io : nullptr};
        evaluateTile(net, n, v, s);
        // The pixels the driver did not write, run by run: the output's channels in fp32, shaded where asked,
        // then converted and stored with the output's stride.
        for (size_t runStart = 0; runStart < n;) {
            if (fused && t.done[runStart]) {  // the driver writes whole vectors
                runStart += size_t(width);
                continue;
            }
            size_t runEnd = runStart + 1;
            while (runEnd < n && !(fused && t.done[runEnd])) ++runEnd;
            const size_t m = runEnd - runStart;
            for (size_t j = runStart; j < runEnd; ++j) {
                float* rgb = t.rgb + 3 * j;
                if (g.surfaces) {
                    NradSurface surface;  // any alignment
                    std::memcpy(&surface, reinterpret_cast<const uint8_t*>(g.surfaces) + (first + j) * surfaceStride, sizeof surface);
                    shadeOne(a, volume, surface, t.n + 3 * j, t.d + 3 * j, rgb);
                }
                float* c = t.color + channels * (j - runStart);
                c[0] = rgb[0];
                c[1] = rgb[1];
                c[2] = rgb[2];
                if (channels == 4) c[3] = 1.0f;
            }
            const void* packed = t.color;
            if (half) {
                conv.toHalf(t.color, t.halves, channels * m);
                packed = t.halves;
            }
            uint8_t* out = static_cast<uint8_t*>(g.output) + (first + runStart) * outStride;
            const auto* bytes = static_cast<const uint8_t*>(packed);
            if (outStride == pixel)
                std::memcpy(out, packed, m * pixel);
            else if (pixel == 6)
                scatterPixels<6>(bytes, out, outStride, m);
            else if (pixel == 8)
                scatterPixels<8>(bytes, out, outStride, m);
            else if (pixel == 12)
                scatterPixels<12>(bytes, out, outStride, m);
            else
                scatterPixels<16>(bytes, out, outStride, m);
            runStart = runEnd;
        }
    }
}

}  // namespace nrad::rt
