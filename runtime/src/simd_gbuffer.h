// simd_impl.h, part 3: G-buffers on vectors of points (strided fp32/fp16 attributes in, shading by the
// material terms, pixels out).
// Only simd_impl.h includes it, inside a kernel file's anonymous namespace: no guard, no includes of its own.

// ----- G-buffers: strided fp32/fp16 attributes in, pixels out (GBufferIo) ----------------------------------------

// N values of type T (float, or fp16 bits) of W records `stride` bytes apart from `s`, reading exactly each
// record's N T: transposed into N rows of W.
template <class V, int N, class T>
inline void copyRows(const uint8_t* s, size_t stride, T rows[N][V::W]) {
    for (int l = 0; l < V::W; ++l, s += stride) {
        T values[N];
        std::memcpy(values, s, sizeof values);
        for (int k = 0; k < N; ++k) rows[k][l] = values[k];
    }
}

template <class V>
inline void loadExact(const StridedAttribute& a, size_t first, typename V::F v[3]) {
    const uint8_t* s = a.base + first * a.stride;
    if (a.half) {
        alignas(64) uint16_t h[3][V::W];
        copyRows<V, 3>(s, a.stride, h);
        for (int k = 0; k < 3; ++k) v[k] = V::loadHalf(h[k]);
    } else {
        alignas(64) float f[3][V::W];
        copyRows<V, 3>(s, a.stride, f);
        for (int k = 0; k < 3; ++k) v[k] = V::load(f[k]);
    }
}

template <class V>
NRAD_ALWAYS_INLINE inline void loadAttribute(const StridedAttribute& a, size_t first, bool wide, typename V::F v[3]) {
    (void)wide;
    if constexpr (V::kStridedLoads) {
        if (wide) {
            const uint8_t* s = a.base + first * a.stride;
            if (a.half)
                V::loadStrided3Half(s, a.stride, v);
            else
                V::loadStrided3(s, a.stride, v);
            return;
        }
    }
    loadExact<V>(a, first, v);
}

// Lanes of v that are finite (inf x 0 and NaN x 0 are NaN).
template <class V>
inline unsigned finiteMask(typename V::F v) {
    return V::equalMask(V::mul(v, V::zero()), V::zero());
}

// v / |v| lane by lane, NaN where |v|^2 is zero or not finite: gbuffer.cpp's normalise(), the same operations
// in the same order.
template <class V>
inline void normalise3(typename V::F v[3]) {
    using F = typename V::F;
    const F zero = V::zero();
    const F len2 = V::add(V::add(V::mul(v[0], v[0]), V::mul(v[1], v[1])), V::mul(v[2], v[2]));
    const unsigned ok = ~V::leMask(len2, zero) & finiteMask<V>(len2);  // > 0 and finite
    const F inv = V::div(V::set1(1.0f), V::sqrt(len2));
    uint32_t nanBits = 0x7FC00000u;
    float nan;
    std::memcpy(&nan, &nanBits, 4);
    for (int k = 0; k < 3; ++k) v[k] = V::select(ok, V::mul(v[k], inv), V::set1(nan));
}

// A block's position, normal and direction from the G-buffer, as gbuffer.cpp's shadeGBuffer prepares them.
template <class V>
NRAD_ALWAYS_INLINE inline void loadGBuffer(const GBufferIo& g, size_t first, typename V::F p[3], typename V::F n[3], typename V::F d[3]) {
    const bool wide = first + size_t(V::W) <= g.safePoints;
    loadAttribute<V>(g.p, first, wide, p);
    loadAttribute<V>(g.n, first, wide, n);
    if (g.eye)
        for (int k = 0; k < 3; ++k) d[k] = V::sub(V::set1(g.eyePosition[k]), p[k]);
    else
        loadAttribute<V>(g.d, first, wide, d);
    if (g.normaliseDirections) normalise3<V>(d);
    if (g.normaliseNormals) normalise3<V>(n);
}

// eval::exp2Poly, operation for operation (no fused multiply-adds): the same bits in every lane.
template <class V>
inline typename V::F exp2Poly(typename V::F x) {
    using F = typename V::F;
    const F xc = V::min(V::max(x, V::set1(-kMaxExp2)), V::set1(kMaxExp2));  // NaN: max gives -kMaxExp2
    const F half = V::select(V::geMask(xc, V::zero()), V::set1(0.5f), V::set1(-0.5f));
    const F n = V::cvtFloat(V::cvtTrunc(V::add(xc, half)));
    const F r = V::mul(V::sub(xc, n), V::set1(kLn2));
    F q = V::set1(kExpP[6]);
    for (int k = 5; k >= 0; --k) q = V::add(V::mul(q, r), V::set1(kExpP[k]));
    return V::timesPow2(q, n);
}

// x clamped to [0, 1] as `x < 0 ? 0 : (x > 1 ? 1 : x)` does, NaN kept.
template <class V>
inline typename V::F clampKeepNaN(typename V::F x) {
    const unsigned number = V::equalMask(x, x);
    const unsigned below = ~V::geMask(x, V::zero()) & number, above = ~V::leMask(x, V::set1(1.0f)) & number;
    return V::select(below, V::zero(), V::select(above, V::set1(1.0f), x));
}

// The final radiance of W points from the asset's (rgb, in place): gbuffer.cpp's shadeOne and nrad/eval.h's
// shade() and reflectance() operation for operation (no fused multiply-adds, the same order, exp2Poly; min/max
// with the x86 NaN rule standing where fmin/fmax or a NaN-discarding comparison stand), so each lane gets the
// scalar path's bits.
template <class V>
inline void shadePixels(const GBufferIo& g, size_t first, const typename V::F n[3], const typename V::F d[3],
                        typename V::F rgb[3]) {
    using F = typename V::F;
    constexpr int W = V::W;
    F m[9];  // baseColor[3], metallic, roughness, specular, emission[3]
    const uint8_t* s = g.surfaces + first * g.surfaceStride;
    if constexpr (V::kSurfaceLoads) {
        V::loadSurfaces(s, g.surfaceStride, m);
    } else {
        alignas(64) float rows[9][W];
        copyRows<V, 9>(s, g.surfaceStride, rows);
        for (int j = 0; j < 9; ++j) m[j] = V::load(rows[j]);
    }
    const F zero = V::zero(), one = V::set1(1.0f);
    F r[3] = {one, one, one};
    if (g.contentFlags & kContentDemodulated) {
        F cosNV = V::add(V::add(V::mul(n[0], d[0]), V::mul(n[1], d[1])), V::mul(n[2], d[2]));
        cosNV = V::select(finiteMask<V>(cosNV), cosNV, zero);
        const F rough = clampKeepNaN<V>(m[4]), metal = clampKeepNaN<V>(m[3]), spec = m[5];
        const F nv = V::min(V::max(cosNV, zero), one);
        const float c0[4] = {-1.0f, -0.0275f, -0.572f, 0.022f}, c1[4] = {1.0f, 0.0425f, 1.04f, -0.04f};
        F rr[4];
        for (int i = 0; i < 4; ++i) rr[i] = V::add(V::mul(rough, V::set1(c0[i])), V::set1(c1[i]));
        const F a004 = V::add(V::mul(V::min(V::mul(rr[0], rr[0]), exp2Poly<V>(V::mul(V::set1(-9.28f), nv))), rr[0]), rr[1]);
        const F A = V::max(V::add(V::mul(V::set1(-1.04f), a004), rr[2]), zero);
        const F B = V::max(V::add(V::mul(V::set1(1.04f), a004), rr[3]), zero);
        const F oneMinusM = V::sub(one, metal);
        const F w = V::add(V::mul(spec, oneMinusM), metal);
        const F f0Spec = V::mul(V::mul(V::set1(0.04f), spec), oneMinusM);
        for (int c = 0; c < 3; ++c) {
            const F base = V::min(V::max(m[c], zero), one);
            const F f0 = V::add(f0Spec, V::mul(base, metal));
            const F out = V::add(V::add(V::mul(base, oneMinusM), V::mul(f0, A)), V::mul(w, B));
            r[c] = V::max(out, zero);
        }
    }
    for (int c = 0; c < 3; ++c) {
        F e = zero;
        if (g.contentFlags & kContentScattered) {
            e = m[6 + c];
            e = V::select(finiteMask<V>(e), e, zero);
        }
        const F out = V::add(V::mul(r[c], rgb[c]), e);
        rgb[c] = V::select(finiteMask<V>(out), out, zero);
    }
}

// W pixels of kBytes (three or four channels of T, the fourth `alpha`) from rows of channels, `stride` bytes apart.
template <class V, size_t kBytes, class T>
inline void writePixels(uint8_t* o, size_t stride, const T rows[3][V::W], T alpha) {
    for (int l = 0; l < V::W; ++l, o += stride) {
        const T px[4] = {rows[0][l], rows[1][l], rows[2][l], alpha};
        std::memcpy(o, px, kBytes);
    }
}

// W pixels of radiance into the G-buffer's output.
template <class V>
inline void storePixels(const GBufferIo& g, size_t first, const typename V::F rgb[3]) {
    uint8_t* o = g.out + first * g.outStride;
    if constexpr (V::kRgbaStores) {
        if (g.outHalf && g.channels == 4) {
            V::storeHalfRgba(o, g.outStride, rgb);
            return;
        }
        if (!g.outHalf && g.channels == 4) {
            V::storeRgba(o, g.outStride, rgb);
            return;
        }
    }
    if (g.channels == 3 && g.outStride == (g.outHalf ? 6u : 12u)) {  // packed RGB: three interleaved vectors
        typename V::F px[3];
        V::interleave3(rgb, px);
        for (int k = 0; k < 3; ++k) {
            if (g.outHalf)
                V::storeHalf(reinterpret_cast<uint16_t*>(o) + k * V::W, px[k]);
            else
                V::store(reinterpret_cast<float*>(o) + k * V::W, px[k]);
        }
        return;
    }
    // Pixel by pixel, copies of a constant size (a copy of the channel count's size was a call to memcpy per pixel).
    if (g.outHalf) {
        alignas(64) uint16_t h[3][V::W];
        for (int c = 0; c < 3; ++c) V::storeHalf(h[c], rgb[c]);
        if (g.channels == 4)
            writePixels<V, 8>(o, g.outStride, h, uint16_t(0x3C00));  // alpha 1
        else
            writePixels<V, 6>(o, g.outStride, h, uint16_t(0x3C00));
    } else {
        alignas(64) float f[3][V::W];
        for (int c = 0; c < 3; ++c) V::store(f[c], rgb[c]);
        if (g.channels == 4)
            writePixels<V, 16>(o, g.outStride, f, 1.0f);
        else
            writePixels<V, 12>(o, g.outStride, f, 1.0f);
    }
}

// eval::localInBox for W points (lattice coordinate t, the box's float(lo) and float(hi - lo)), clamped to
// [-1, 1]: the position input of a point with one support.
template <class V>
inline typename V::F localInBox(typename V::F t, typename V::F lo, typename V::F size) {
    const typename V::F one = V::set1(1.0f);
    const typename V::F q = V::sub(V::div(V::mul(V::set1(2.0f), V::sub(t, lo)), size), one);
    return V::min(V::max(q, V::set1(-1.0f)), one);
}
