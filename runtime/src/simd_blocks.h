// simd_impl.h, part 4: the block driver (locating whole vectors in grid voxels or kd-tree leaves, recording
// the points left to the grouped pass, evalBlocks and its steps) and the interleave tables the kernels use.
// Only simd_impl.h includes it, inside a kernel file's anonymous namespace: no guard, no includes of its own.

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
// both blocks where they share a network and `pairs` (the kernel has the registers), else one after the other with
// their output transforms together (toRadianceTwo).
template <class V>
NRAD_ALWAYS_INLINE inline void evalStep(const BlockContext& ctx, bool pairs, int count, const int32_t network[2],
                                        const typename V::F in[2][kInputs], typename V::F out[2][kOutputs]) {
    if (pairs && count == 2 && network[0] >= 0 && network[0] == network[1]) {
        const NetworkView net = networkAt(ctx, network[0]);
        evalNetworkPair<V>(net, in, out);
        for (int j = 0; j < 2; ++j) toRadiance<V>(net, out[j]);
    } else if (count == 2 && network[0] >= 0 && network[1] >= 0) {  // one after the other, transformed together
        const NetworkView a = networkAt(ctx, network[0]), b = networkAt(ctx, network[1]);
        evalNetwork<V>(a, in[0], out[0]);
        evalNetwork<V>(b, in[1], out[1]);
        toRadianceTwo<V>(a, b, out);
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
    // pairs too, evaluating them one after the other: faster than one block per step on most G-buffer formats and
    // batches (docs/design.md).
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
        NRAD_UNROLL(2)  // both blocks' values in registers where they fit (docs/design.md)
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
