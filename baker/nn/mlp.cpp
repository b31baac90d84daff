// Forward pass and backpropagation of the per-voxel networks.
#include "baker/nn/mlp.h"

#include <algorithm>
#include <cmath>

#if defined(__SSE2__)
#include <emmintrin.h>
#endif

namespace nrad {

size_t NetworkShape::parameterCount() const {
    size_t n = 0, in = size_t(inputs);
    for (int w : hidden) {
        n += size_t(w) * in + size_t(w);
        in = size_t(w);
    }
    return n + size_t(outputs) * in + size_t(outputs);
}

int NetworkShape::maxWidth() const {
    int m = std::max(inputs, outputs);
    for (int w : hidden) m = std::max(m, w);
    return m;
}

Mlp::Mlp(NetworkShape shape) : shape_(std::move(shape)), params_(shape_.parameterCount(), 0.0f) {
    size_t at = 0;
    int in = shape_.inputs;
    const size_t layers = shape_.hidden.size() + 1;
    for (size_t l = 0; l < layers; ++l) {
        int out = l + 1 == layers ? shape_.outputs : shape_.hidden[l];
        offset_.push_back(at);
        at += size_t(out) * size_t(in) + size_t(out);
        in = out;
    }
}

void Mlp::initialize(uint64_t seed, float outputBias) {
    SplitMix64 rng(seed);
    size_t at = 0;
    int in = shape_.inputs;
    size_t layers = shape_.hidden.size() + 1;
    for (size_t l = 0; l < layers; ++l) {
        bool last = l + 1 == layers;
        int out = last ? shape_.outputs : shape_.hidden[l];
        float limit = std::sqrt(6.0f / float(in));
        for (int i = 0; i < out * in; ++i) params_[at++] = (2.0f * rng.uniform() - 1.0f) * limit;
        for (int i = 0; i < out; ++i) params_[at++] = last ? outputBias : 0.01f;
        in = out;
    }
}

namespace {
void prepare(const NetworkShape& shape, MlpWorkspace& ws) {
    const size_t layers = shape.hidden.size() + 1;
    if (ws.at.size() == layers + 2) return;
    ws.at.assign(1, 0);
    ws.at.push_back(size_t(shape.inputs));
    for (size_t l = 0; l < layers; ++l) ws.at.push_back(ws.at.back() + size_t(l + 1 == layers ? shape.outputs : shape.hidden[l]));
    ws.values.assign(ws.at.back(), 0.0f);
    ws.deltas.assign(ws.at.back(), 0.0f);
}
}  // namespace

// Each output's sum runs from its bias up in input order (as nrad/eval.h's forward), all outputs of a layer at
// once so that their chains overlap.
void Mlp::forward(const float* x, float* y, MlpWorkspace& ws) const {
    prepare(shape_, ws);
    const size_t layers = shape_.hidden.size() + 1;
    std::copy(x, x + shape_.inputs, ws.values.begin());
    int in = shape_.inputs;
    for (size_t l = 0; l < layers; ++l) {
        const bool last = l + 1 == layers;
        const int out = last ? shape_.outputs : shape_.hidden[l];
        const float* W = params_.data() + offset_[l];
        const float* b = W + size_t(out) * size_t(in);
        const float* prev = ws.values.data() + ws.at[l];
        float* a = ws.values.data() + ws.at[l + 1];
        for (int o = 0; o < out; ++o) a[o] = b[o];
        for (int i = 0; i < in; ++i) {
            const float xi = prev[i];
            for (int o = 0; o < out; ++o) a[o] += W[size_t(o) * size_t(in) + size_t(i)] * xi;
        }
        if (!last)
            for (int o = 0; o < out; ++o) a[o] = std::max(0.0f, a[o]);
        in = out;
    }
    std::copy(ws.values.begin() + std::ptrdiff_t(ws.at[layers]), ws.values.begin() + std::ptrdiff_t(ws.at[layers + 1]), y);
}

void Mlp::backward(const float* dy, MlpWorkspace& ws, float* grad) const {
    const size_t layers = shape_.hidden.size() + 1;
    std::copy(dy, dy + shape_.outputs, ws.deltas.begin() + std::ptrdiff_t(ws.at[layers]));
    for (size_t l = layers; l-- > 0;) {
        const int out = l + 1 == layers ? shape_.outputs : shape_.hidden[l];
        const int in = l == 0 ? shape_.inputs : shape_.hidden[l - 1];
        const float* W = params_.data() + offset_[l];
        float* gW = grad + offset_[l];
        float* gb = gW + size_t(out) * size_t(in);
        const float* prev = ws.values.data() + ws.at[l];
        const float* delta = ws.deltas.data() + ws.at[l + 1];
        for (int o = 0; o < out; ++o) {
            const float d = delta[o];
            if (d == 0.0f) continue;
            gb[o] += d;
            for (int i = 0; i < in; ++i) gW[size_t(o) * size_t(in) + size_t(i)] += d * prev[i];
        }
        if (l == 0) break;
        // The previous layer's deltas: each a sum over outputs in output order, zero for inactive units.
        float* back = ws.deltas.data() + ws.at[l];
        for (int i = 0; i < in; ++i) back[i] = 0.0f;
        for (int o = 0; o < out; ++o) {
            const float d = delta[o];
            for (int i = 0; i < in; ++i) back[i] += W[size_t(o) * size_t(in) + size_t(i)] * d;
        }
        for (int i = 0; i < in; ++i)
            if (prev[i] <= 0.0f) back[i] = 0.0f;  // ReLU'(z) = 0 for inactive units
    }
}

namespace {
constexpr int B = MlpBatchWorkspace::kMaxBatch;
constexpr int kLanes = 8;  // samples per vector below, and the partial sums of the per-parameter sums over the batch

// Eight float lanes: two SSE2 registers on x86-64 (every x86-64 has them), plain arrays elsewhere. Each lane
// does exactly the scalar operations (a multiply, then an add: no fused multiply-add), so the kernels below
// give the same bits as the per-sample pass on any machine.
#if defined(__SSE2__)
struct V8 {
    __m128 lo, hi;
};
inline V8 splat(float x) { return {_mm_set1_ps(x), _mm_set1_ps(x)}; }
inline V8 load(const float* p) { return {_mm_loadu_ps(p), _mm_loadu_ps(p + 4)}; }
inline void store(float* p, const V8& v) {
    _mm_storeu_ps(p, v.lo);
    _mm_storeu_ps(p + 4, v.hi);
}
inline V8 operator+(const V8& a, const V8& b) { return {_mm_add_ps(a.lo, b.lo), _mm_add_ps(a.hi, b.hi)}; }
inline V8 operator*(const V8& a, const V8& b) { return {_mm_mul_ps(a.lo, b.lo), _mm_mul_ps(a.hi, b.hi)}; }
// p > 0 ? v : 0, lane by lane (NaN in p gives 0, as the comparison does).
inline V8 whereAboveZero(const V8& p, const V8& v) {
    const __m128 z = _mm_setzero_ps();
    return {_mm_and_ps(v.lo, _mm_cmpgt_ps(p.lo, z)), _mm_and_ps(v.hi, _mm_cmpgt_ps(p.hi, z))};
}
#else
struct V8 {
    float f[kLanes];
};
inline V8 splat(float x) {
    V8 v;
    for (float& f : v.f) f = x;
    return v;
}
inline V8 load(const float* p) {
    V8 v;
    for (int j = 0; j < kLanes; ++j) v.f[j] = p[j];
    return v;
}
inline void store(float* p, const V8& v) {
    for (int j = 0; j < kLanes; ++j) p[j] = v.f[j];
}
inline V8 operator+(const V8& a, const V8& b) {
    V8 v;
    for (int j = 0; j < kLanes; ++j) v.f[j] = a.f[j] + b.f[j];
    return v;
}
inline V8 operator*(const V8& a, const V8& b) {
    V8 v;
    for (int j = 0; j < kLanes; ++j) v.f[j] = a.f[j] * b.f[j];
    return v;
}
inline V8 whereAboveZero(const V8& p, const V8& v) {
    V8 r;
    for (int j = 0; j < kLanes; ++j) r.f[j] = p.f[j] > 0.0f ? v.f[j] : 0.0f;
    return r;
}
#endif

// The lanes added up in lane order, from zero.
inline float sumInOrder(const V8& v) {
    float lanes[kLanes];
    store(lanes, v);
    float s = 0.0f;
    for (int j = 0; j < kLanes; ++j) s += lanes[j];
    return s;
}

// out[q] = sumInOrder(v[q]) for q < count: on SSE2 four at a time, transposed so that each lane adds up one
// vector's lanes (the same additions in the same order).
inline void sumsInOrder(const V8* v, int count, float* out) {
    int q = 0;
#if defined(__SSE2__)
    for (; q + 4 <= count; q += 4) {
        __m128 a0 = v[q].lo, a1 = v[q + 1].lo, a2 = v[q + 2].lo, a3 = v[q + 3].lo;
        __m128 b0 = v[q].hi, b1 = v[q + 1].hi, b2 = v[q + 2].hi, b3 = v[q + 3].hi;
        _MM_TRANSPOSE4_PS(a0, a1, a2, a3);
        _MM_TRANSPOSE4_PS(b0, b1, b2, b3);
        __m128 s = _mm_setzero_ps();
        s = _mm_add_ps(s, a0);
        s = _mm_add_ps(s, a1);
        s = _mm_add_ps(s, a2);
        s = _mm_add_ps(s, a3);
        s = _mm_add_ps(s, b0);
        s = _mm_add_ps(s, b1);
        s = _mm_add_ps(s, b2);
        s = _mm_add_ps(s, b3);
        _mm_storeu_ps(out + q, s);
    }
#endif
    for (; q < count; ++q) out[q] = sumInOrder(v[q]);
}

void prepareBatch(const NetworkShape& shape, MlpBatchWorkspace& ws) {
    const size_t layers = shape.hidden.size() + 1;
    if (ws.at.size() == layers + 2) return;
    ws.at.assign(1, 0);
    ws.at.push_back(size_t(shape.inputs) * B);
    for (size_t l = 0; l < layers; ++l) ws.at.push_back(ws.at.back() + size_t(l + 1 == layers ? shape.outputs : shape.hidden[l]) * B);
    ws.values.assign(ws.at.back(), 0.0f);
    ws.deltas.assign(ws.at.back(), 0.0f);
}

}  // namespace

void Mlp::forwardBatch(const float* x, int count, MlpBatchWorkspace& ws) const {
    prepareBatch(shape_, ws);
    ws.count = count;
    const int n = (count + kLanes - 1) / kLanes * kLanes;  // padded samples hold zeros: finite, no gradient
    for (int i = 0; i < shape_.inputs; ++i) {
        float* v = ws.value(0, i);
        for (int k = 0; k < count; ++k) v[k] = x[size_t(k) * size_t(shape_.inputs) + size_t(i)];
        for (int k = count; k < n; ++k) v[k] = 0.0f;
    }
    int in = shape_.inputs;
    for (size_t l = 0; l < layers(); ++l) {
        const bool last = l + 1 == layers();
        const int out = last ? shape_.outputs : shape_.hidden[l];
        const float* W = params_.data() + offset_[l];
        const float* b = W + size_t(out) * size_t(in);
        const float* prev = ws.value(l, 0);
        for (int o = 0; o < out; ++o) {
            float* a = ws.value(l + 1, o);
            const float* w = W + size_t(o) * size_t(in);
            // kLanes samples at a time, each one's sum in a register from the bias up in input order.
            for (int k0 = 0; k0 < n; k0 += kLanes) {
                V8 acc = splat(b[o]);
                for (int i = 0; i < in; ++i) acc = acc + splat(w[i]) * load(prev + size_t(i) * B + size_t(k0));
                store(a + k0, last ? acc : whereAboveZero(acc, acc));
            }
        }
        in = out;
    }
}

void Mlp::backwardBatch(MlpBatchWorkspace& ws, float* grad) const {
    const int n = (ws.count + kLanes - 1) / kLanes * kLanes;
    const size_t L = layers();
    for (int o = 0; o < shape_.outputs; ++o) {
        float* d = ws.delta(L, o);
        for (int k = ws.count; k < n; ++k) d[k] = 0.0f;
    }
    for (size_t l = L; l-- > 0;) {
        const int out = l + 1 == L ? shape_.outputs : shape_.hidden[l];
        const int in = l == 0 ? shape_.inputs : shape_.hidden[l - 1];
        const float* W = params_.data() + offset_[l];
        float* gW = grad + offset_[l];
        float* gb = gW + size_t(out) * size_t(in);
        const float* prev = ws.value(l, 0);
        for (int o = 0; o < out; ++o) {
            // Every weight's and the bias's sum over the batch in kLanes partial sums, added up in lane order;
            // four weights at a time, their partial sums in registers.
            const float* d = ws.delta(l + 1, o);
            int g = 0;
            for (; g + 4 <= in; g += 4) {
                const float *p0 = prev + size_t(g) * B, *p1 = p0 + B, *p2 = p1 + B, *p3 = p2 + B;
                V8 acc[4] = {splat(0.0f), splat(0.0f), splat(0.0f), splat(0.0f)};
                for (int k = 0; k < n; k += kLanes) {
                    const V8 dk = load(d + k);
                    acc[0] = acc[0] + dk * load(p0 + k);
                    acc[1] = acc[1] + dk * load(p1 + k);
                    acc[2] = acc[2] + dk * load(p2 + k);
                    acc[3] = acc[3] + dk * load(p3 + k);
                }
                float sums[4];
                sumsInOrder(acc, 4, sums);
                for (int q = 0; q < 4; ++q) gW[size_t(o) * size_t(in) + size_t(g + q)] += sums[q];
            }
            for (; g < in; ++g) {
                const float* pg = prev + size_t(g) * B;
                V8 acc = splat(0.0f);
                for (int k = 0; k < n; k += kLanes) acc = acc + load(d + k) * load(pg + k);
                gW[size_t(o) * size_t(in) + size_t(g)] += sumInOrder(acc);
            }
            V8 bias = splat(0.0f);
            for (int k = 0; k < n; k += kLanes) bias = bias + load(d + k);
            gb[o] += sumInOrder(bias);
        }
        if (l == 0) break;
        // The previous layer's deltas: each sample's sum over outputs in output order, in a register, zero for
        // inactive units (ReLU'(z) = 0).
        const float* next = ws.delta(l + 1, 0);
        for (int i = 0; i < in; ++i) {
            float* back = ws.delta(l, i);
            const float* p = ws.value(l, i);
            for (int k0 = 0; k0 < n; k0 += kLanes) {
                V8 acc = splat(0.0f);
                for (int o = 0; o < out; ++o) acc = acc + splat(W[size_t(o) * size_t(in) + size_t(i)]) * load(next + size_t(o) * B + size_t(k0));
                store(back + k0, whereAboveZero(load(p + k0), acc));
            }
        }
    }
}

bool Mlp::allFinite() const {
    return std::all_of(params_.begin(), params_.end(), [](float p) { return std::isfinite(p); });
}

}  // namespace nrad
