// simd_impl.h, part 2: a batch's coordinates as vectors (load3 / store3, SoA or interleaved) and blocks
// blended in registers (evalBlended).
// Only simd_impl.h includes it, inside a kernel file's anonymous namespace: no guard, no includes of its own.

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
