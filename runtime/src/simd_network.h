// simd_impl.h, part 1: networks on vectors of points (exp(x) - 1, the output transform, a network of any
// topology or of the default 9-9-3 one on one or two vectors, the chunk kernel).
// Only simd_impl.h includes it, inside a kernel file's anonymous namespace: no guard, no includes of its own.

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

// toRadiance on two blocks' outputs at once (networks a and b of one asset), lane for lane the same operations:
// exp(x) - 1 is a chain of about fourteen dependent operations, and three chains at a time (one block) left the
// multiply-add pipes idle for most of their latency; six interleaved fill them. Every step whose blocks are
// evaluated one after the other: AVX2's always (with the partial sums below, 1.1x its coherent batch rate:
// docs/design.md), AVX-512's and NEON's when the two blocks have different networks.
template <class V>
NRAD_ALWAYS_INLINE inline void toRadianceTwo(const NetworkView& a, const NetworkView& b, typename V::F out[2][kOutputs]) {
    using F = typename V::F;
    constexpr int kValues = 2 * kOutputs;
    F v[kValues];
    for (int c = 0; c < kValues; ++c) v[c] = out[c / kOutputs][c % kOutputs];
    if (a.exponential) {  // one asset: b's transform is a's
        F n[kValues], r[kValues], q[kValues];
        for (int c = 0; c < kValues; ++c) v[c] = V::min(V::max(v[c], V::set1(kExpLo)), V::set1(kExpHi));
        for (int c = 0; c < kValues; ++c) n[c] = V::roundNearest(V::mul(v[c], V::set1(kLog2e)));
        for (int c = 0; c < kValues; ++c) r[c] = V::fnmadd(n[c], V::set1(kLn2Lo), V::fnmadd(n[c], V::set1(kLn2Hi), v[c]));
        for (int c = 0; c < kValues; ++c) q[c] = V::set1(kExpP[6]);
        for (int k = 5; k >= 0; --k)
            for (int c = 0; c < kValues; ++c) q[c] = V::fmadd(q[c], r[c], V::set1(kExpP[k]));
        for (int c = 0; c < kValues; ++c) v[c] = V::sub(V::timesPow2(q[c], n[c]), V::set1(1.0f));
    }
    for (int c = 0; c < kValues; ++c) {
        const F scale = V::set1(c < kOutputs ? a.scale : b.scale);
        out[c / kOutputs][c % kOutputs] = V::min(V::max(V::mul(v[c], scale), V::zero()), V::set1(eval::kMaxRadiance));
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
    // each hidden unit feeds the outputs as soon as it is computed. Two partial sums per hidden unit halve its
    // chain of dependent multiply-adds (with 16 vector registers too: docs/design.md); with 32, two
    // per output too (with 16 those would spill).
    const F zero = V::zero();
    const float* W1 = net.params;
    const float* b1 = W1 + 9 * 9;
    const float* W2 = b1 + 9;
    const float* b2 = W2 + 3 * 9;
    if (V::kRegisters < 32) {  // two partial sums per hidden unit, one per output (nine inputs held: 16 fit)
        for (int c = 0; c < 3; ++c) out[c] = V::set1(b2[c]);
        NRAD_UNROLL(9)
        for (int j = 0; j < 9; ++j) {
            F h0 = V::set1(b1[j]), h1 = V::mul(V::set1(W1[j * 9 + 8]), in[8]);
            for (int i = 0; i < 8; i += 2) {
                h0 = V::fmadd(V::set1(W1[j * 9 + i]), in[i], h0);
                h1 = V::fmadd(V::set1(W1[j * 9 + i + 1]), in[i + 1], h1);
            }
            const F h = V::max(V::add(h0, h1), zero);
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
// out-of-order window to overlap (the gain: docs/design.md).
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
