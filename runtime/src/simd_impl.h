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
//   kHalfRgbaStore: whether it has storeHalfRgba (three F as W fp16 RGBA pixels of alpha 1, `stride` bytes apart);
//   kSurfaceLoads: whether it has loadSurfaces (W NradSurfaces' nine floats, `stride` bytes apart, as nine F).

// exp(x) - 1 in the polynomial of kernels.h (input clamped to [kExpLo, kExpHi]).
template <class V>
inline typename V::F expMinusOne(typename V::F v) {
    using F = typename V::F;
    F xe = V::min(V::max(v, V::set1(kExpLo)), V::set1(kExpHi));
    F n = V::roundNearest(V::mul(xe, V::set1(kLog2e)));
    F r = V::fnmadd(n, V::set1(kLn2Lo), V::fnmadd(n, V::set1(kLn2Hi), xe));
    F q = V::set1(kExpP[6]);
    for (int k = 5; k >= 0; --k) q = V::fmadd(q, r, V::set1(kExpP[k]));
    return V::sub(V::timesPow2(q, n), V::set1(1.0f));
}

// The network's three outputs -> radiance: output transform, the voxel's scale, clamped to [0, kMaxRadiance].
// The scaled value is max's first operand, so a NaN output yields 0.
template <class V>
inline void toRadiance(const NetworkView& net, typename V::F out[3]) {
    for (int c = 0; c < kOutputs; ++c) {
        typename V::F v = net.exponential ? expMinusOne<V>(out[c]) : out[c];
        out[c] = V::min(V::max(V::mul(v, V::set1(net.scale)), V::zero()), V::set1(eval::kMaxRadiance));
    }
}

// Any topology, layer by layer through two arrays of vectors.
template <class V>
NRAD_NOINLINE void evalNetworkGeneric(const NetworkView& net, const typename V::F in[kInputs],
                                                  typename V::F out[kOutputs]) {
    using F = typename V::F;
    const F zero = V::zero();
    F a[kMaxWidth], b[kMaxWidth];
    int width = kInputs;
    for (int i = 0; i < kInputs; ++i) a[i] = in[i];
    const float* w = net.params;
    for (uint32_t l = 0; l <= net.hiddenLayers; ++l) {
        bool last = l == net.hiddenLayers;
        int next = last ? kOutputs : int(net.hiddenWidths[l]);
        const float* bias = w + next * width;
        for (int o = 0; o < next; ++o) {
            F s = V::set1(bias[o]);
            const float* row = w + o * width;
            for (int i = 0; i < width; ++i) s = V::fmadd(V::set1(row[i]), a[i], s);
            b[o] = last ? s : V::max(s, zero);
        }
        for (int o = 0; o < next; ++o) a[o] = b[o];
        w = bias + next;
        width = next;
    }
    for (int c = 0; c < kOutputs; ++c) out[c] = a[c];
}

// A loop unrolled whole: GCC left the 9-9-3 network's loop over hidden units rolled (a counter, a branch on the
// unit's parity and pointer updates between every unit's multiply-adds), and the block driver's loop over its pair.
#if defined(__GNUC__)
#define NRAD_UNROLL_PRAGMA(x) _Pragma(#x)
#define NRAD_UNROLL(n) NRAD_UNROLL_PRAGMA(GCC unroll n)
#else
#define NRAD_UNROLL(n)
#endif

// One network on W points: in[9] -> out[3] (network outputs, before the output transform).
template <class V>
NRAD_ALWAYS_INLINE inline void evalNetwork(const NetworkView& net, const typename V::F in[kInputs],
                                                       typename V::F out[kOutputs]) {
    using F = typename V::F;
    if (!(net.hiddenLayers == 1 && net.hiddenWidths[0] == 9)) return evalNetworkGeneric<V>(net, in, out);
    // The default topology, 9-9-3, every size known at compile time: everything stays in registers, and
    // each hidden unit feeds the outputs as soon as it is computed. With 32 vector registers, two partial
    // sums per hidden unit and per output halve the chains of dependent multiply-adds; with 16 they would
    // spill.
    const F zero = V::zero();
    const float* W1 = net.params;
    const float* b1 = W1 + 9 * 9;
    const float* W2 = b1 + 9;
    const float* b2 = W2 + 3 * 9;
    if (V::kRegisters < 32) {
        for (int c = 0; c < 3; ++c) out[c] = V::set1(b2[c]);
        NRAD_UNROLL(9)
        for (int j = 0; j < 9; ++j) {
            F h = V::set1(b1[j]);
            for (int i = 0; i < 9; ++i) h = V::fmadd(V::set1(W1[j * 9 + i]), in[i], h);
            h = V::max(h, zero);
            for (int c = 0; c < 3; ++c) out[c] = V::fmadd(V::set1(W2[c * 9 + j]), h, out[c]);
        }
        return;
    }
    F o0[3], o1[3];
    for (int c = 0; c < 3; ++c) {
        o0[c] = V::set1(b2[c]);
        o1[c] = zero;
    }
    NRAD_UNROLL(9)
    for (int j = 0; j < 9; ++j) {
        F h0 = V::set1(b1[j]), h1 = V::mul(V::set1(W1[j * 9 + 8]), in[8]);
        for (int i = 0; i < 8; i += 2) {
            h0 = V::fmadd(V::set1(W1[j * 9 + i]), in[i], h0);
            h1 = V::fmadd(V::set1(W1[j * 9 + i + 1]), in[i + 1], h1);
        }
        F h = V::max(V::add(h0, h1), zero);
        for (int c = 0; c < 3; ++c) {
            if (j % 2 == 0)
                o0[c] = V::fmadd(V::set1(W2[c * 9 + j]), h, o0[c]);
            else
                o1[c] = V::fmadd(V::set1(W2[c * 9 + j]), h, o1[c]);
        }
    }
    for (int c = 0; c < 3; ++c) out[c] = V::add(o0[c], o1[c]);
}

// Two vectors of points through one network of the default topology (9-9-3) at once, each exactly as evalNetwork
// computes it with 32 registers (the same operations in the same order): every weight is loaded once for both,
// and the two vectors' chains of dependent multiply-adds interleave. One vector at a time is bound by the loads
// of the weights (one per multiply-add) and by those chains, which a vector's other work is too long for the
// out-of-order window to overlap (AVX-512, coherent points in cache: 12-14% more evaluations per second).
template <class V>
NRAD_ALWAYS_INLINE inline void evalNetworkPair(const NetworkView& net, const typename V::F in[2][kInputs],
                                               typename V::F out[2][kOutputs]) {
    using F = typename V::F;
    const F zero = V::zero();
    const float* W1 = net.params;
    const float* b1 = W1 + 9 * 9;
    const float* W2 = b1 + 9;
    const float* b2 = W2 + 3 * 9;
    F o0[2][3], o1[2][3];
    for (int v = 0; v < 2; ++v)
        for (int c = 0; c < 3; ++c) {
            o0[v][c] = V::set1(b2[c]);
            o1[v][c] = zero;
        }
    NRAD_UNROLL(9)
    for (int j = 0; j < 9; ++j) {
        F h[2];
        for (int v = 0; v < 2; ++v) {
            F h0 = V::set1(b1[j]), h1 = V::mul(V::set1(W1[j * 9 + 8]), in[v][8]);
            for (int i = 0; i < 8; i += 2) {
                h0 = V::fmadd(V::set1(W1[j * 9 + i]), in[v][i], h0);
                h1 = V::fmadd(V::set1(W1[j * 9 + i + 1]), in[v][i + 1], h1);
            }
            h[v] = V::max(V::add(h0, h1), zero);
        }
        for (int v = 0; v < 2; ++v)
            for (int c = 0; c < 3; ++c) {
                if (j % 2 == 0)
                    o0[v][c] = V::fmadd(V::set1(W2[c * 9 + j]), h[v], o0[v][c]);
                else
                    o1[v][c] = V::fmadd(V::set1(W2[c * 9 + j]), h[v], o1[v][c]);
            }
    }
    for (int v = 0; v < 2; ++v)
        for (int c = 0; c < 3; ++c) out[v][c] = V::add(o0[v][c], o1[v][c]);
}

// ChunkKernel: the first `count` of kChunk points in SoA rows, whole vectors.
template <class V>
void evalChunk(const NetworkView& net, const float* x, float* y, int count) {
    for (int p = 0; p < count; p += V::W) {
        typename V::F in[kInputs], out[kOutputs];
        for (int i = 0; i < kInputs; ++i) in[i] = V::load(x + i * kChunk + p);
        evalNetwork<V>(net, in, out);
        toRadiance<V>(net, out);
        for (int c = 0; c < kOutputs; ++c) V::store(y + c * kChunk + p, out[c]);
    }
}

// Three coordinates of W points starting at point `first`: SoA (Stride 1) or interleaved (Stride 3).
template <class V, int Stride>
inline void load3(const float* const src[3], size_t first, typename V::F v[3]) {
    if (Stride == 1) {
        for (int k = 0; k < 3; ++k) v[k] = V::load(src[k] + first);
    } else {
        const float* s = src[0] + 3 * first;
        V::deinterleave3(V::load(s), V::load(s + V::W), V::load(s + 2 * V::W), v);
    }
}

template <class V, int Stride>
inline void store3(float* const dst[3], size_t first, const typename V::F v[3]) {
    if (Stride == 1) {
        for (int k = 0; k < 3; ++k) V::store(dst[k] + first, v[k]);
    } else {
        typename V::F o[3];
        V::interleave3(v, o);
        float* d = dst[0] + 3 * first;
        for (int k = 0; k < 3; ++k) V::store(d + k * V::W, o[k]);
    }
}

// A block of W located points, some of them in a blending band: eval::supports() and keepOccupied() for
// every lane at once, then, for every voxel of the small box the block's supports span, that voxel's network
// over the whole vector, each lane accumulating weight x radiance in voxel order (the order, rounding and
// arithmetic of the grouped pass in evaluation.cpp, so a point gets the same bits whichever path it takes).
// Returns false, writing nothing, when the box holds more than kMaxBoxVoxels voxels (an incoherent block) or
// some lane is left without an occupied support (the general path flags it). A block whose points all lie in one
// voxel (`oneVoxel`: a surface's run) is blended whatever its box, at most the voxel and its 26 neighbours: the
// more lanes a vector has, the likelier its points reach into bands on both sides of an axis, and 27 networks over
// the vector cost less than its in-band points one by one through the general path (blended 16^3 grid, points
// sorted by voxel, M evaluations/s: AVX-512 9.1 -> 16.4, AVX2 11.8 -> 13.5; incoherent blocks are unchanged).
constexpr int kMaxBoxVoxels = 8, kMaxVoxelBox = 27;

template <class V>
bool evalBlended(const BlockContext& ctx, const typename V::F t[3], const typename V::F n[3], const typename V::F d[3],
                 const typename V::I c[3], typename V::F acc[3], bool oneVoxel) {
    using F = typename V::F;
    constexpr int W = V::W;
    constexpr unsigned all = W == 32 ? ~0u : (1u << W) - 1u;
    const LocateGrid& g = ctx.grid;
    const F zero = V::zero(), one = V::set1(1.0f), two = V::set1(2.0f), band = V::set1(g.band);
    // Per axis (t: the grid coordinate, c: the voxel coordinate, both from the block driver): the voxel
    // coordinate as a float, the lanes in the lower / upper band, the weights of the voxel below, the own
    // voxel and the voxel above, the clamp reach, and the coordinates the block spans.
    F cf[3], w[3][3], reach[3];
    unsigned lo[3], hi[3];
    int from[3], to[3];
    for (int k = 0; k < 3; ++k) {
        cf[k] = V::cvtFloat(c[k]);
        const F f = V::sub(t[k], cf[k]);
        lo[k] = V::geMask(cf[k], one) & ~V::geMask(f, band) & all;  // eval::bandSide == -1
        hi[k] = V::leMask(cf[k], V::set1(float(g.dims[k]) - 2.0f)) & ~V::leMask(f, V::set1(1.0f - g.band)) & ~lo[k] & all;
        const F x = V::select(hi[k], V::sub(t[k], V::add(cf[k], one)), f);  // t - the face's coordinate
        F u = V::div(V::add(x, band), V::set1(2.0f * g.band));  // eval::aboveFaceWeight
        u = V::min(V::max(u, zero), one);
        const F above = V::mul(V::mul(u, u), V::sub(V::set1(3.0f), V::mul(two, u)));
        const F below = V::sub(one, above);
        w[k][0] = below;
        w[k][1] = V::select(lo[k], above, V::select(hi[k], below, one));
        w[k][2] = above;
        reach[k] = V::select(lo[k] | hi[k], V::set1(1.0f + 2.0f * g.band), one);
        alignas(64) int32_t lanes[W];
        V::storei(lanes, c[k]);
        from[k] = lanes[0];
        to[k] = lanes[0];
        for (int l = 0; l < W; ++l) {
            const int a = lanes[l] - int((lo[k] >> l) & 1u), b = lanes[l] + int((hi[k] >> l) & 1u);
            from[k] = a < from[k] ? a : from[k];
            to[k] = b > to[k] ? b : to[k];
        }
    }
    if ((to[0] - from[0] + 1) * (to[1] - from[1] + 1) * (to[2] - from[2] + 1) > kMaxBoxVoxels && !oneVoxel) return false;
    // Each lane's weight for coordinate X of axis k: its own voxel's, the one below's or the one above's,
    // else 0; for every coordinate of the box (at most kMaxBoxVoxels along one axis).
    F axisWeight[3][kMaxBoxVoxels];
    for (int k = 0; k < 3; ++k)
        for (int X = from[k]; X <= to[k]; ++X) {
            const unsigned own = V::equalMask(c[k], V::seti(X));
            const unsigned below = V::equalMask(c[k], V::seti(X + 1)) & lo[k];
            const unsigned above = V::equalMask(c[k], V::seti(X - 1)) & hi[k];
            axisWeight[k][X - from[k]] = V::select(own, w[k][1], V::select(below, w[k][0], V::select(above, w[k][2], zero)));
        }
    // The occupied supports in voxel order (z, y, x, lower first) and the per-lane sum of their weights.
    struct Term {
        int32_t network;
        int coord[3];
        F raw;
    };
    Term terms[kMaxVoxelBox];
    int count = 0;
    F sum = zero;
    for (int z = from[2]; z <= to[2]; ++z) {
        const F wz = axisWeight[2][z - from[2]];
        for (int y = from[1]; y <= to[1]; ++y) {
            const F wy = axisWeight[1][y - from[1]];
            for (int x = from[0]; x <= to[0]; ++x) {
                const F raw = V::mul(V::mul(axisWeight[0][x - from[0]], wy), wz);
                if ((~V::leMask(raw, zero) & all) == 0) continue;  // no lane has weight > 0 here
                const int32_t network = g.dense[x + int32_t(g.dims[0]) * (y + int32_t(g.dims[1]) * z)];
                if (network < 0) continue;
                terms[count++] = {network, {x, y, z}, raw};
                sum = V::add(sum, raw);
            }
        }
    }
    if ((~V::leMask(sum, zero) & all) != all) return false;
    for (int ch = 0; ch < 3; ++ch) acc[ch] = zero;
    for (int i = 0; i < count; ++i) {
        const Term& term = terms[i];
        F in[kInputs] = {zero, zero, zero, n[0], n[1], n[2], d[0], d[1], d[2]};
        for (int k = 0; k < 3; ++k) {
            const F q = V::sub(V::mul(two, V::sub(t[k], V::set1(float(term.coord[k])))), one);
            in[k] = V::min(V::max(q, V::sub(zero, reach[k])), reach[k]);
        }
        NetworkView net = ctx.networks;
        net.params += size_t(term.network) * ctx.paramsPerNetwork;
        net.scale = ctx.scales[term.network];
        F out[kOutputs];
        evalNetwork<V>(net, in, out);
        toRadiance<V>(net, out);
        const unsigned kept = ~V::leMask(term.raw, zero) & all;
        const F weight = V::div(term.raw, sum);
        for (int ch = 0; ch < 3; ++ch) acc[ch] = V::select(kept, V::add(acc[ch], V::mul(weight, out[ch])), acc[ch]);
    }
    return true;
}

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
    if constexpr (V::kHalfRgbaStore) {
        if (g.outHalf && g.channels == 4) {
            V::storeHalfRgba(o, g.outStride, rgb);
            return;
        }
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

// A block's points, one by one: those in `keep` whose cell has a network join the grouped pass (one entry of
// weight 1 with its position input, flag written); every other goes to def.points for the general path.
template <class V>
inline void recordLanes(Deferred& def, uint8_t* flags, size_t first, unsigned keep, const int32_t networks[V::W],
                        const float local[3][V::W]) {
    for (int l = 0; l < V::W; ++l) {
        const uint32_t point = uint32_t(first + size_t(l));
        if (!((keep >> l) & 1u) || networks[l] < 0) {
            def.points[def.pointCount++] = point;
            continue;
        }
        const size_t e = def.count++;
        def.index[e] = point;
        def.network[e] = networks[l];
        for (int k = 0; k < 3; ++k) def.local[3 * e + size_t(k)] = local[k][l];
        if (flags) flags[point] = 0;
    }
}

// Every lane's leaf (lattice coordinates t inside the lattice, dims: the lattice's) by the planes alone: from
// the rectilinear table where the tree has one, else the lane's start-table cell's entry, then down the tree
// while any lane is at an inner node, one level at a time. A point inside a leaf's open box has that leaf
// alone (eval::treeSupports' descent takes the same side of every plane: t >= split there is t - split >= 0).
template <class V>
inline typename V::I treeLeaves(const LocateTree& tree, const uint32_t dims[3], const typename V::F t[3]) {
    using F = typename V::F;
    using I = typename V::I;
    I at = V::seti(0);
    if (tree.rectLeaves) {  // the rectilinear table: each lane's lattice voxel, its cell, its leaf
        for (int k = 0; k < 3; ++k) {  // t >= 0 here, so the truncation is >= 0 (the grid's voxel coordinate)
            const I c = V::mini(V::cvtTrunc(t[k]), V::seti(int(dims[k]) - 1));
            at = V::addi(at, V::gatheri(tree.rectAxis + tree.rectOffset[k], c));
        }
        return V::gatheri(tree.rectLeaves, at);
    }
    for (int k = 2; k >= 0; --k) {  // t >= 0 here, so the truncation is >= 0
        const I c = V::mini(V::cvtTrunc(V::mul(t[k], V::set1(tree.startScale[k]))), V::seti(int(tree.startDims[k]) - 1));
        at = V::addi(V::mullo(at, V::seti(int(tree.startDims[k]))), c);
    }
    I node = V::gatheri(tree.starts, at);
    const F zero = V::zero();
    const I zeroi = V::seti(0), onei = V::seti(1), three = V::seti(3);
    for (;;) {
        const unsigned inner = V::geMask(V::cvtFloat(node), zero);
        if (!inner) break;
        // Four independent gathers per level (a finished lane reads node 0's), so that a level costs one
        // gather's latency.
        const I at1 = V::selecti(inner, node, zeroi), word = V::mullo(at1, three);
        const I axis = V::gatheri(tree.nodes, word);
        const F split = V::gatherf(tree.splits, at1);
        const I lower = V::gatheri(tree.nodes + 1, word), upper = V::gatheri(tree.nodes + 2, word);
        const F along = V::select(V::equalMask(axis, zeroi), t[0], V::select(V::equalMask(axis, onei), t[1], t[2]));
        node = V::selecti(inner, V::selecti(V::geMask(along, split), upper, lower), node);
    }
    return V::addi(V::mullo(node, V::seti(-1)), V::seti(-1));  // the leaf: -1 - node (tagged)
}

// The lanes of t inside `leaf`'s open box (LocateTree::leaves), as a mask.
template <class V>
inline unsigned insideLeaf(const LocateTree& tree, int32_t leaf, const typename V::F t[3]) {
    const float* box = tree.leaves + 12 * size_t(leaf);
    unsigned inside = ~0u;
    for (int k = 0; k < 3; ++k) inside &= ~V::leMask(t[k], V::set1(box[k])) & ~V::geMask(t[k], V::set1(box[3 + k]));
    return inside;
}

// The position input of a vector of points that have `leaf` alone, exactly as eval::treeSupports computes it.
template <class V>
inline void treeLeafInputs(const LocateTree& tree, int32_t leaf, const typename V::F t[3], typename V::F in[3]) {
    const float* box = tree.leaves + 12 * size_t(leaf);
    for (int k = 0; k < 3; ++k) in[k] = localInBox<V>(t[k], V::set1(box[6 + k]), V::set1(box[9 + k]));
}

// A block of valid points of a kd-tree asset spread over several leaves (or not all clear of the bands), each
// lane's leaf found (treeLeaves): each point with its leaf alone (inside the leaf's open box; on an unblended
// tree, every point), in a leaf with a network, joins the grouped pass with weight 1 (its flag written), as a
// grid block spanning several voxels does; every other point goes to def.points, for the general path to
// locate (bands, empty leaves). The boxes and position inputs (eval::localInBox, clamped) are computed for the
// whole vector.
template <class V>
void recordTreeLanes(const BlockContext& ctx, const typename V::F t[3], typename V::I leaves, size_t first, Deferred& def,
                     uint8_t* flags) {
    constexpr int W = V::W;
    constexpr unsigned all = W == 32 ? ~0u : (1u << W) - 1u;
    const LocateTree& tree = ctx.tree;
    alignas(64) int32_t networks[W];
    V::storei(networks, V::gatheri(ctx.grid.dense, leaves));
    const typename V::I box = V::mullo(leaves, V::seti(12));
    unsigned inside = all;
    alignas(64) float local[3][W];
    for (int k = 0; k < 3; ++k) {
        const float* b = tree.leaves + k;
        if (ctx.grid.band > 0.0f)
            inside &= ~V::leMask(t[k], V::gatherf(b, box)) & ~V::geMask(t[k], V::gatherf(b + 3, box));
        V::store(local[k], localInBox<V>(t[k], V::gatherf(b + 6, box), V::gatherf(b + 9, box)));
    }
    recordLanes<V>(def, flags, first, inside, networks, local);
}

// A G-buffer block's prepared inputs into BatchIo's arrays, for the paths that read them there.
template <class V, int Stride>
inline void spill(const BatchIo& io, size_t first, const typename V::F p[3], const typename V::F n[3], const typename V::F d[3]) {
    store3<V, Stride>(const_cast<float* const*>(io.p), first, p);
    store3<V, Stride>(const_cast<float* const*>(io.n), first, n);
    store3<V, Stride>(const_cast<float* const*>(io.d), first, d);
}

// A block of a kd-tree asset whose points are valid and inside the grid: located in the last vector's leaf or in
// one leaf for the whole vector, its position inputs written to `in` and its leaf's network returned, for
// evaluation in registers; or, spread over leaves (or in a band), each point recorded by itself (recordTreeLanes)
// and -1 returned.
template <class V, int Stride>
NRAD_ALWAYS_INLINE inline int32_t locateTreeBlock(const BlockContext& ctx, const LocateGrid& g, const BatchIo& io, size_t first,
                                                  const typename V::F t[3], const typename V::F p[3], const typename V::F n[3],
                                                  const typename V::F d[3], int32_t& lastLeaf, Deferred& def, typename V::F in[kInputs]) {
    using I = typename V::I;
    constexpr unsigned all = V::W == 32 ? ~0u : (1u << V::W) - 1u;
    int32_t leaf = -1;
    if (lastLeaf >= 0 && (insideLeaf<V>(ctx.tree, lastLeaf, t) & all) == all) {  // runs on one surface
        leaf = lastLeaf;
    } else {
        const I leaves = treeLeaves<V>(ctx.tree, g.dims, t);
        const int32_t leaf0 = V::firstLane(leaves);
        if (V::equalMask(leaves, V::seti(leaf0)) == all && g.dense[leaf0] >= 0 &&
            (!(g.band > 0.0f) || (insideLeaf<V>(ctx.tree, leaf0, t) & all) == all)) {
            leaf = leaf0;
        } else {
            if (io.gbuffer) spill<V, Stride>(io, first, p, n, d);  // the other paths read BatchIo
            recordTreeLanes<V>(ctx, t, leaves, first, def, io.flags);
            return -1;
        }
    }
    treeLeafInputs<V>(ctx.tree, leaf, t, in);
    lastLeaf = leaf;
    NRAD_COUNT_FOR_TESTS(def.treeBlocks);
    return g.dense[leaf];
}

// The network view of network k (ctx.networks is network 0's).
inline NetworkView networkAt(const BlockContext& ctx, int32_t k) {
    NetworkView net = ctx.networks;
    net.params += size_t(k) * ctx.paramsPerNetwork;
    net.scale = ctx.scales[k];
    return net;
}

// The networks of a step's blocks (count from its first; -1: none) over their inputs, into their outputs: once for
// both blocks where they share a network and `pairs` (the kernel has the registers), else block by block.
template <class V>
NRAD_ALWAYS_INLINE inline void evalStep(const BlockContext& ctx, bool pairs, int count, const int32_t network[2],
                                        const typename V::F in[2][kInputs], typename V::F out[2][kOutputs]) {
    if (pairs && count == 2 && network[0] >= 0 && network[0] == network[1]) {
        const NetworkView net = networkAt(ctx, network[0]);
        evalNetworkPair<V>(net, in, out);
        for (int j = 0; j < 2; ++j) toRadiance<V>(net, out[j]);
    } else {
        for (int j = 0; j < count; ++j) {
            if (network[j] < 0) continue;
            const NetworkView net = networkAt(ctx, network[j]);
            evalNetwork<V>(net, in[j], out[j]);
            toRadiance<V>(net, out[j]);
        }
    }
}

// The blocks of a step that have results (count from block `pair`), written: into the G-buffer's pixels (shaded
// in place first when it has surfaces) or BatchIo::out.
template <class V, int Stride>
NRAD_ALWAYS_INLINE inline void writeBlocks(const BatchIo& io, size_t pair, int count, const bool result[2],
                                           typename V::F in[2][kInputs], typename V::F out[2][kOutputs], Deferred& def) {
    constexpr int W = V::W;
    const GBufferIo* const gb = io.gbuffer;
    for (int j = 0; j < count; ++j) {
        if (!result[j]) continue;
        const size_t first = (pair + size_t(j)) * size_t(W);
        if (gb) {
            if (gb->surfaces) shadePixels<V>(*gb, first, &in[j][3], &in[j][6], out[j]);
            storePixels<V>(*gb, first, out[j]);
            std::memset(gb->done + first, 1, W);
            NRAD_COUNT_FOR_TESTS(def.gbufferBlocks);
        } else {
            store3<V, Stride>(io.out, first, out[j]);
        }
        if (io.flags) std::memset(io.flags + first, 0, W);
    }
    (void)def;
}

// BlockDriver (kernels.h), for one layout. Blocks are taken two at a time: each is read, checked and located on
// its own (deferred, recorded point by point or blended there; kd-tree assets in locateTreeBlock), two that need
// the same network are evaluated together (evalNetworkPair, where the kernel has the registers), and the blocks
// with results are written last (writeBlocks).
template <class V, int Stride>
void evalBlocks(const BlockContext& ctx, size_t blocks, Deferred& def) {
    using F = typename V::F;
    using I = typename V::I;
    constexpr int W = V::W;
    constexpr unsigned all = W == 32 ? ~0u : (1u << W) - 1u;
    // The grid's and the batch's descriptions as locals: as far as the compiler knows, the stores through def's and
    // the caller's pointers below could change ctx, which made it reload and recompute these for every vector.
    const LocateGrid g = ctx.grid;
    const BatchIo io = ctx.io;
    const GBufferIo* const gb = io.gbuffer;
    const bool tree = ctx.tree.leaves != nullptr, banded = g.band > 0.0f;
    // Two blocks per step: the pair's network evaluated once where the kernel has the registers for it. AVX2 takes
    // pairs too, evaluating them one after the other: 2-5% faster on most G-buffer formats and batches, 2-3% slower
    // on shaded G-buffers than one block per step.
    constexpr int kStep = 2;
    const bool pairs = V::kRegisters >= 32 && ctx.networks.hiddenLayers == 1 && ctx.networks.hiddenWidths[0] == 9;
    const F one = V::set1(1.0f), minusOne = V::set1(-1.0f), two = V::set1(2.0f);
    F lower[3], upper[3], factor[3], belowTop[3];
    I last[3];
    for (int k = 0; k < 3; ++k) {
        lower[k] = V::set1(g.lower[k]);
        upper[k] = V::set1(g.upper[k]);
        factor[k] = V::set1(g.factor[k]);
        belowTop[k] = V::set1(float(g.dims[k]) - 2.0f);
        last[k] = V::seti(int(g.dims[k]) - 1);
    }
    const F band = V::set1(g.band), farBand = V::set1(1.0f - g.band);
    int32_t lastLeaf = -1;  // kd-tree assets: the leaf of the last vector evaluated in registers
    for (size_t pair = 0; pair < blocks; pair += kStep) {
        const int count = pair + 1 < blocks ? kStep : 1;
        // Per block: the network its inputs go through (-1: none; a blended block has its result already), whether
        // it has a result to write, its inputs (the normal and direction in 3..8 for every block with a result).
        int32_t network[2] = {-1, -1};
        bool result[2] = {false, false};
        F in[2][kInputs], out[2][kOutputs];
        NRAD_UNROLL(2)  // both blocks' values in registers where they fit (6-10% more coherent evaluations per second)
        for (int j = 0; j < count; ++j) {
            const size_t b = pair + size_t(j), first = b * size_t(W);
            F p[3], n[3], d[3];
            if (gb) {
                loadGBuffer<V>(*gb, first, p, n, d);
            } else {
                load3<V, Stride>(io.p, first, p);
                load3<V, Stride>(io.n, first, n);
                load3<V, Stride>(io.d, first, d);
            }
            // Finite normal and direction: 0 x (their sum) is 0, not NaN (a sum that overflows only sends the
            // block to the general path). Positions inside [lower, upper] (false for NaN): the format's rule.
            F sum = V::add(V::add(V::add(n[0], n[1]), V::add(n[2], d[0])), V::add(d[1], d[2]));
            unsigned ok = finiteMask<V>(sum);
            for (int k = 0; k < 3; ++k) ok &= V::geMask(p[k], lower[k]) & V::leMask(p[k], upper[k]);
            if (ok != all) {  // some point is invalid or outside: the general path takes the block, from BatchIo
                if (gb) spill<V, Stride>(io, first, p, n, d);
                def.blocks[def.blockCount++] = uint32_t(b);
                continue;
            }
            for (int k = 0; k < 3; ++k) {
                in[j][3 + k] = n[k];
                in[j][6 + k] = d[k];
            }
            F t[3];
            for (int k = 0; k < 3; ++k) t[k] = V::mul(V::sub(p[k], lower[k]), factor[k]);  // eval::gridCoordinate
            if (tree) {  // a kd-tree asset: the last vector's leaf, one leaf for the vector, or each point in its own
                network[j] = locateTreeBlock<V, Stride>(ctx, g, io, first, t, p, n, d, lastLeaf, def, in[j]);
                result[j] = network[j] >= 0;
                continue;
            }
            // The voxel and the position inside it, exactly as eval::supports() computes them for a point in no
            // blending band (eval::bandSide); a block with a point in a band is blended by evalBlended (or, when
            // it spans too many voxels, takes the general path).
            I c[3];
            unsigned inBand = 0;
            for (int k = 0; k < 3; ++k) {
                c[k] = V::mini(V::cvtTrunc(t[k]), last[k]);  // t >= 0 here
                F cf = V::cvtFloat(c[k]), f = V::sub(t[k], cf);
                if (banded) {  // c > 0 && f < band, or c + 1 < dims && f > 1 - band (f is never NaN here)
                    inBand |= V::geMask(cf, one) & ~V::geMask(f, band);
                    inBand |= V::leMask(cf, belowTop[k]) & ~V::leMask(f, farBand);
                }
                F l = V::sub(V::mul(two, f), one);
                in[j][k] = V::min(V::max(l, minusOne), one);
            }
            I voxel = V::addi(c[0], V::mullo(V::seti(int(g.dims[0])), V::addi(c[1], V::mullo(V::seti(int(g.dims[1])), c[2]))));
            const int32_t voxel0 = V::firstLane(voxel);
            if (inBand & all) {  // blended: in registers when the block spans a few voxels
                if (evalBlended<V>(ctx, t, n, d, c, out[j], V::equalMask(voxel, V::seti(voxel0)) == all)) {
                    NRAD_COUNT_FOR_TESTS(def.blendedBlocks);
                    result[j] = true;
                    continue;
                }
            } else if (V::equalMask(voxel, V::seti(voxel0)) == all && g.dense[voxel0] >= 0) {  // one occupied voxel
                network[j] = g.dense[voxel0];
                result[j] = true;
                continue;
            }
            // Point by point: one outside every band, in an occupied voxel, has that voxel alone with weight 1 and
            // joins the grouped pass with its position input; any other (in a band of a block evalBlended could
            // not take, or in an empty voxel) goes to the general path by itself.
            if (gb) spill<V, Stride>(io, first, p, n, d);  // the other paths read BatchIo
            alignas(64) int32_t voxels[W], networks[W];
            V::storei(voxels, voxel);
            for (int l = 0; l < W; ++l) networks[l] = g.dense[voxels[l]];
            alignas(64) float lanes[3][W];
            for (int k = 0; k < 3; ++k) V::store(lanes[k], in[j][k]);
            recordLanes<V>(def, io.flags, first, ~inBand & all, networks, lanes);
        }
        evalStep<V>(ctx, pairs, count, network, in, out);
        writeBlocks<V, Stride>(io, pair, count, result, in, out, def);
    }
}

// The constant tables of deinterleave3 / interleave3 for W lanes. Element e of the three interleaved
// vectors (x0 y0 z0 x1 ...) is component e % 3 of point e / 3; it sits in vector e / W, lane e % W.
template <int W>
struct Interleave {
    // Lanes of vector s that hold component c.
    static constexpr unsigned laneMask(int s, int c) {
        unsigned m = 0;
        for (int l = 0; l < W; ++l)
            if ((s * W + l) % 3 == c) m |= 1u << l;
        return m;
    }
    template <int S, int C>
    static constexpr unsigned kMask = laneMask(S, C);
    // After blending the three vectors by laneMask (lane l from the vector holding component c there),
    // point k's component c is at lane (3k + c) % W: gather[c][k]. scatter is its inverse.
    struct Tables {
        int32_t gather[3][W];
        int32_t scatter[3][W];
    };
    static constexpr Tables tables() {
        Tables t{};
        for (int c = 0; c < 3; ++c)
            for (int k = 0; k < W; ++k) {
                t.gather[c][k] = (3 * k + c) % W;
                t.scatter[c][(3 * k + c) % W] = k;
            }
        return t;
    }
};
