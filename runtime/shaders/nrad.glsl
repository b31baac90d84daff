// libnrad's shading path for GPUs: evaluate and shade one surface point from an asset packed by
// nradPackGpuBuffer (docs/runtime.md, "GPU buffers"). GLSL 4.50, core features only; include it in any stage.
//
// The arithmetic is the evaluation contract of formats/include/nrad/eval.h, line for line: how a point finds its
// networks (the uniform grid, or the kd-tree, blended across faces), the nine inputs, the forward pass, the
// output transform, and the recombination with the surface's material. The CPU runtime is the reference;
// tests/gpu holds this file to it on lavapipe within the tolerance docs/runtime.md states.
//
// It includes nrad_gpu_layout.h (the buffer's word offsets), which is installed beside it; where a toolchain has
// no includes, paste nrad_gpu_layout.h, then this file.
//
// Before including, optionally:
//   #define NRAD_ASSET_BINDING n    the storage buffer's binding (default 0)
//   #define NRAD_ASSET_SET s        its descriptor set, Vulkan only (default 0)
//   #define NRAD_NO_BUFFER_DECLARATION  and declare `uint nradWords[]` (readonly std430) yourself
//
// Then:
//   uint nradEvaluate(vec3 position, vec3 normal, vec3 towardsViewer, out vec3 radiance)
//       what the asset stores at the point (NRAD_CONTENT_* in nradContentFlags()); returns NRAD_POINT_* flags
//   uint nradShade(vec3 position, vec3 normal, vec3 towardsViewer, NradSurface surface, out vec3 radiance)
//       the final radiance towards the viewer (reflectance and emission recombined as the asset says)
//   uint nradEvaluateVolume(vec3 position, vec3 normal, out vec3 radiance)
//       the light in the volume, E(x, n) / pi, for receivers that were not in the bake (moving objects)
//   uint nradShadeVolume(vec3 position, vec3 normal, vec3 towardsViewer, NradSurface surface, out vec3 radiance)
//       such a receiver's radiance towards the viewer (eval.h's shadeVolume)
// Normals and directions unit length, world space, the normal on the viewer's side (as nradEvaluateBatch).
#ifndef NRAD_GLSL
#define NRAD_GLSL

#ifndef NRAD_ASSET_BINDING
#define NRAD_ASSET_BINDING 0
#endif
#ifndef NRAD_ASSET_SET
#define NRAD_ASSET_SET 0
#endif
#ifndef NRAD_NO_BUFFER_DECLARATION
#ifdef VULKAN
layout(std430, set = NRAD_ASSET_SET, binding = NRAD_ASSET_BINDING) readonly buffer NradAssetBuffer { uint nradWords[]; };
#else
layout(std430, binding = NRAD_ASSET_BINDING) readonly buffer NradAssetBuffer { uint nradWords[]; };
#endif
#endif

// nrad.h's constants. (The file is written in the subset GLSL and HLSL share, with GLSL's names: nrad.hlsl maps them,
// declares the buffer and includes this file. So no array constructors, no vector splats, no bare global consts,
// and no function with out parameters, or any costly one, inside ?: (HLSL evaluates both sides).)
#ifndef NRAD_CONST
#define NRAD_CONST const
#endif
NRAD_CONST uint NRAD_POINT_OK = 0u;
NRAD_CONST uint NRAD_POINT_OUTSIDE_GRID = 1u;
NRAD_CONST uint NRAD_POINT_EMPTY_VOXEL = 2u;
NRAD_CONST uint NRAD_POINT_INVALID_INPUT = 4u;
NRAD_CONST uint NRAD_CONTENT_SCATTERED_RADIANCE = 1u;
NRAD_CONST uint NRAD_CONTENT_DEMODULATED = 2u;
NRAD_CONST uint NRAD_CONTENT_BLENDED = 4u;
NRAD_CONST uint NRAD_CONTENT_TREE = 8u;
NRAD_CONST int NRAD_GPU_MAX_HIDDEN_WIDTH = 32;
NRAD_CONST int NRAD_MAX_SUPPORTS = 8;

// The header's word offsets, shared with the runtime's packer: nrad_gpu_layout.h, installed beside this file
// (pasted before it where a toolchain has no includes, which its guard then skips).
#ifndef NRAD_GPU_LAYOUT_H
#include "nrad_gpu_layout.h"
#endif

// The material terms a G-buffer holds (nrad.h's NradSurface).
struct NradSurface {
    vec3 baseColor;  // linear, textures applied
    float metallic;
    float roughness;  // perceptual
    float specular;  // KHR_materials_specular factor, 1 if none
    vec3 emission;  // radiance emitted towards the viewer
};

float nradFloat(uint word) { return uintBitsToFloat(nradWords[word]); }
uint nradContentFlags() { return nradWords[NRAD_GPU_WORD_CONTENT_FLAGS]; }
bool nradFinite(float v) { return (floatBitsToUint(v) & 0x7F800000u) != 0x7F800000u; }
bool nradFinite3(vec3 v) { return nradFinite(v.x) && nradFinite(v.y) && nradFinite(v.z); }

// ----- how a point finds its networks (eval.h: supports, treeSupports, keepOccupied) -----------------------

int nradVoxelCoordinate(float t, uint dim) {
    int i = int(t);
    return i >= int(dim) ? int(dim) - 1 : (i < 0 ? 0 : i);
}

float nradAboveFaceWeight(float x, float band) {
    float u = (x + band) / (2.0 * band);
    u = u < 0.0 ? 0.0 : (u > 1.0 ? 1.0 : u);
    return u * u * (3.0 - 2.0 * u);
}

float nradClampReach(float q, float reach) { return q < -reach ? -reach : (q > reach ? reach : q); }

// The grid's supports: count (0 outside), cells, weights and position inputs.
int nradGridSupports(vec3 p, out int cells[NRAD_MAX_SUPPORTS], out float weights[NRAD_MAX_SUPPORTS],
                     out vec3 locals[NRAD_MAX_SUPPORTS]) {
    float band = nradFloat(NRAD_GPU_WORD_BAND);
    int lowCoord[3], count[3];
    float upWeight[3], t[3];
    uint dims[3];
    for (int k = 0; k < 3; ++k) {
        uint kk = uint(k);
        float lower = nradFloat(NRAD_GPU_WORD_LOWER + kk), upper = nradFloat(NRAD_GPU_WORD_UPPER + kk);
        dims[k] = nradWords[NRAD_GPU_WORD_DIMS + kk];
        if (!(p[k] >= lower && p[k] <= upper)) return 0;
        precise float tk = (p[k] - lower) * nradFloat(NRAD_GPU_WORD_FACTOR + kk);
        t[k] = tk;
        int c = nradVoxelCoordinate(tk, dims[k]);
        precise float f = tk - float(c);
        int side = 0;
        if (band > 0.0) {
            if (c > 0 && f < band) side = -1;
            else if (c + 1 < int(dims[k]) && f > 1.0 - band) side = 1;
        }
        if (side == 0) {
            count[k] = 1;
            lowCoord[k] = c;
            upWeight[k] = 0.0;
        } else {
            int below = side < 0 ? c - 1 : c;
            precise float x = tk - float(below + 1);
            count[k] = 2;
            lowCoord[k] = below;
            upWeight[k] = nradAboveFaceWeight(x, band);
        }
    }
    int n = 0;
    for (int z = 0; z < count[2]; ++z)
        for (int y = 0; y < count[1]; ++y)
            for (int x = 0; x < count[0]; ++x) {
                int c[3], sel[3];
                c[0] = lowCoord[0] + x;
                c[1] = lowCoord[1] + y;
                c[2] = lowCoord[2] + z;
                sel[0] = x;
                sel[1] = y;
                sel[2] = z;
                float w = 1.0;
                vec3 local;
                for (int k = 0; k < 3; ++k) {
                    float wk = count[k] == 1 ? 1.0 : (sel[k] == 1 ? upWeight[k] : 1.0 - upWeight[k]);
                    w = k == 0 ? wk : w * wk;
                    float reach = count[k] == 1 ? 1.0 : 1.0 + 2.0 * band;
                    precise float q = 2.0 * (t[k] - float(c[k])) - 1.0;
                    local[k] = nradClampReach(q, reach);
                }
                cells[n] = c[0] + int(dims[0]) * (c[1] + int(dims[1]) * c[2]);
                weights[n] = w;
                locals[n] = local;
                ++n;
            }
    return n;
}

// The kd-tree's supports, in leaf order (eval::treeSupports, descending from the root).
int nradTreeSupports(vec3 p, out int cells[NRAD_MAX_SUPPORTS], out float weights[NRAD_MAX_SUPPORTS],
                     out vec3 locals[NRAD_MAX_SUPPORTS]) {
    float band = nradFloat(NRAD_GPU_WORD_BAND);
    vec3 t;
    for (int k = 0; k < 3; ++k) {
        uint kk = uint(k);
        float lower = nradFloat(NRAD_GPU_WORD_LOWER + kk), upper = nradFloat(NRAD_GPU_WORD_UPPER + kk);
        if (!(p[k] >= lower && p[k] <= upper)) return 0;
        precise float tk = (p[k] - lower) * nradFloat(NRAD_GPU_WORD_FACTOR + kk);
        t[k] = tk;
    }
    uint nodes = nradWords[NRAD_GPU_WORD_NODES], widths = nradWords[NRAD_GPU_WORD_WIDTHS];
    uint stackNode[NRAD_MAX_SUPPORTS];
    vec3 stackWeight[NRAD_MAX_SUPPORTS];
    int top = 0, n = 0;
    uint node = 0u;
    vec3 w = vec3(1.0, 1.0, 1.0);
    bvec3 blended = bvec3(false, false, false);
    for (;;) {
        for (;;) {
            uint word = nradWords[nodes + 2u * node];
            uint axis = word & 3u;
            if (axis == NRAD_GPU_TREE_LEAF) break;
            int k = int(axis);
            uint child = nradWords[nodes + 2u * node + 1u];
            precise float x = t[k] - float(word >> 2u);
            float width = nradFloat(widths + node);
            if (width > 0.0 && x > -width && x < width && top < NRAD_MAX_SUPPORTS) {
                float above = nradAboveFaceWeight(x, width);
                blended[k] = true;
                stackNode[top] = child + 1u;
                vec3 up = w;
                up[k] = up[k] * above;
                stackWeight[top] = up;
                ++top;
                w[k] = w[k] * (1.0 - above);
                node = child;
            } else {
                node = x >= 0.0 ? child + 1u : child;
            }
        }
        if (n < NRAD_MAX_SUPPORTS) {
            cells[n] = int(nradWords[nodes + 2u * node + 1u]);
            weights[n] = w.x * w.y * w.z;
            ++n;
        }
        if (top == 0) break;
        --top;
        node = stackNode[top];
        w = stackWeight[top];
    }
    uint boxes = nradWords[NRAD_GPU_WORD_BOXES];
    for (int i = 0; i < n; ++i) {
        uint b = boxes + 6u * uint(cells[i]);
        vec3 local;
        for (int k = 0; k < 3; ++k) {
            float lo = float(nradWords[b + uint(k)]), hi = float(nradWords[b + 3u + uint(k)]);
            float reach = blended[k] ? 1.0 + 2.0 * band : 1.0;
            precise float q = 2.0 * (t[k] - lo) / (hi - lo) - 1.0;
            local[k] = nradClampReach(q, reach);
        }
        locals[i] = local;
    }
    return n;
}

// ----- the network and its output (eval.h: forward, expMinusOne, decodeOutput) -----------------------------

// The fp16 parameter at half index `index` of the buffer (two per word, the low half first).
float nradWeight(uint index) {
    vec2 pair = unpackHalf2x16(nradWords[index >> 1u]);
    return (index & 1u) != 0u ? pair.y : pair.x;
}

// exp(r) for |r| <= ln2 / 2 (eval_constants.h kExpP), times 2^n from its exponent bits.
float nradExpPolynomial(float r, float n) {
    float q = 0.00138889090;
    q = q * r + 0.00833336264;
    q = q * r + 0.0416666567;
    q = q * r + 0.166666672;
    q = q * r + 0.5;
    q = q * r + 1.0;
    q = q * r + 1.0;
    return q * uintBitsToFloat(uint(int(n) + 127) << 23u);
}

float nradExpMinusOne(float v) {
    if ((floatBitsToUint(v) & 0x7FFFFFFFu) > 0x7F800000u) return v;  // NaN stays NaN (the caller maps it to 0)
    float xe = v < -87.0 ? -87.0 : (v > 80.0 ? 80.0 : v);
    float n = float(int(xe * 1.44269504 + (xe >= 0.0 ? 0.5 : -0.5)));
    float r = (xe - n * 0.693359375) - n * -2.12194440e-4;
    return nradExpPolynomial(r, n) - 1.0;
}

// The default 9-9-3 network with every loop bound a constant, so that compilers unroll it and keep the
// activations in registers (the general loop below indexes arrays with run-time bounds, which GPUs put in
// local memory). The same sums in the same order as the general loop.
vec3 nradForward993(uint w, vec3 local, vec3 normal, vec3 direction) {
    float x[9];
    for (int i = 0; i < 3; ++i) {
        x[i] = local[i];
        x[3 + i] = normal[i];
        x[6 + i] = direction[i];
    }
    float h[9];
    for (int o = 0; o < 9; ++o) {
        float s = nradWeight(w + 81u + uint(o));
        for (int i = 0; i < 9; ++i) s += nradWeight(w + uint(9 * o + i)) * x[i];
        h[o] = s > 0.0 ? s : 0.0;
    }
    vec3 y;
    for (int o = 0; o < 3; ++o) {
        float s = nradWeight(w + 117u + uint(o));
        for (int i = 0; i < 9; ++i) s += nradWeight(w + 90u + uint(9 * o + i)) * h[i];
        y[o] = s;
    }
    return y;
}

// Any topology the layout allows (hidden widths up to NRAD_GPU_MAX_HIDDEN_WIDTH): the last layer's outputs.
vec3 nradForward(uint w, vec3 local, vec3 normal, vec3 direction) {
    float a[NRAD_GPU_MAX_HIDDEN_WIDTH];
    float b[NRAD_GPU_MAX_HIDDEN_WIDTH];
    for (int i = 0; i < 3; ++i) {
        a[i] = local[i];
        a[3 + i] = normal[i];
        a[6 + i] = direction[i];
    }
    uint layers = nradWords[NRAD_GPU_WORD_HIDDEN_LAYERS];
    uint inputs = 9u;
    for (uint l = 0u; l <= layers; ++l) {
        bool last = l == layers;
        uint outputs = last ? 3u : nradWords[NRAD_GPU_WORD_HIDDEN_WIDTHS + l];
        uint bias = w + outputs * inputs;
        for (uint o = 0u; o < outputs; ++o) {
            float s = nradWeight(bias + o);
            for (uint i = 0u; i < inputs; ++i) s += nradWeight(w + o * inputs + i) * a[i];
            b[o] = last || s > 0.0 ? s : 0.0;
        }
        for (uint o = 0u; o < outputs; ++o) a[o] = b[o];
        w = bias + outputs;
        inputs = outputs;
    }
    return vec3(a[0], a[1], a[2]);
}

// Radiance of network `net` (decoded: transform, scale, clamped to [0, 1e30]) for the nine inputs; `scales` and
// `weights`: the word offsets of the networks' output scales and fp16 weights (the surfaces' or the volume's);
// `transform`: their output transform (NRAD_GPU_WORD_OUTPUT_TRANSFORM or NRAD_GPU_WORD_VOLUME_OUTPUT_TRANSFORM's).
vec3 nradNetwork(uint scales, uint weights, uint transform, int net, vec3 local, vec3 normal, vec3 direction) {
    uint w = 2u * weights + uint(net) * nradWords[NRAD_GPU_WORD_PARAMS];  // half index of the network's first parameter
    bool default993 = nradWords[NRAD_GPU_WORD_HIDDEN_LAYERS] == 1u && nradWords[NRAD_GPU_WORD_HIDDEN_WIDTHS] == 9u;
    vec3 y;
    if (default993) y = nradForward993(w, local, normal, direction);
    else y = nradForward(w, local, normal, direction);
    bool exponential = transform == 1u;
    float scale = nradFloat(scales + uint(net));
    vec3 rgb;
    for (int c = 0; c < 3; ++c) {
        float v = (exponential ? nradExpMinusOne(y[c]) : y[c]) * scale;
        v = v > 0.0 ? v : 0.0;
        rgb[c] = v < 1e30 ? v : 1e30;  // eval::kMaxRadiance
    }
    return rgb;
}

// ----- evaluation ---------------------------------------------------------------------------------------------

// The networks at a point: those of the cell table at word `table` (the surfaces' or the volume's, whose scales
// and weights are at words `scales` and `weightWords`, decoded by `transform`), blended by the partition's supports.
uint nradEvaluateNetworks(uint table, uint scales, uint weightWords, uint transform, vec3 position, vec3 normal, vec3 direction, out vec3 radiance) {
    radiance = vec3(0.0, 0.0, 0.0);
    if (!nradFinite3(position) || !nradFinite3(normal) || !nradFinite3(direction)) return NRAD_POINT_INVALID_INPUT;
    int cells[NRAD_MAX_SUPPORTS];
    float weights[NRAD_MAX_SUPPORTS];
    vec3 locals[NRAD_MAX_SUPPORTS];
    int count;  // (if, not ?: : HLSL evaluates both sides of a conditional, and both would write the supports)
    if (nradWords[NRAD_GPU_WORD_TREE_NODES] == 0u) count = nradGridSupports(position, cells, weights, locals);
    else count = nradTreeSupports(position, cells, weights, locals);
    if (count == 0) return NRAD_POINT_OUTSIDE_GRID;
    // keepOccupied: drop supports without a network (or weight 0), renormalise the rest in order.
    int nets[NRAD_MAX_SUPPORTS];
    int kept = 0;
    float sum = 0.0;
    for (int i = 0; i < count; ++i) {
        int net = int(nradWords[table + uint(cells[i])]);
        if (weights[i] > 0.0 && net >= 0) {
            nets[kept] = net;
            weights[kept] = weights[i];
            locals[kept] = locals[i];
            sum += weights[i];
            ++kept;
        }
    }
    if (kept == 0) return NRAD_POINT_EMPTY_VOXEL;
    for (int i = 0; i < kept; ++i) radiance += (weights[i] / sum) * nradNetwork(scales, weightWords, transform, nets[i], locals[i], normal, direction);
    return NRAD_POINT_OK;
}

uint nradEvaluate(vec3 position, vec3 normal, vec3 direction, out vec3 radiance) {
    return nradEvaluateNetworks(nradWords[NRAD_GPU_WORD_CELL_TABLE], nradWords[NRAD_GPU_WORD_SCALES], nradWords[NRAD_GPU_WORD_WEIGHTS],
                                nradWords[NRAD_GPU_WORD_OUTPUT_TRANSFORM], position, normal, direction, radiance);
}

// The light in the volume (nradEvaluateVolumeBatch): E(x, n) / pi at any point of the grid for a unit normal, from the
// volume's networks (the normal is their direction input too). An asset without them: 0, NRAD_POINT_EMPTY_VOXEL.
uint nradEvaluateVolume(vec3 position, vec3 normal, out vec3 radiance) {
    if (nradWords[NRAD_GPU_WORD_VOLUME_NETWORKS] == 0u) {
        radiance = vec3(0.0, 0.0, 0.0);
        return nradFinite3(position) && nradFinite3(normal) ? NRAD_POINT_EMPTY_VOXEL : NRAD_POINT_INVALID_INPUT;
    }
    return nradEvaluateNetworks(nradWords[NRAD_GPU_WORD_VOLUME_CELL_TABLE], nradWords[NRAD_GPU_WORD_VOLUME_SCALES],
                                nradWords[NRAD_GPU_WORD_VOLUME_WEIGHTS], nradWords[NRAD_GPU_WORD_VOLUME_OUTPUT_TRANSFORM], position,
                                normal, normal, radiance);
}

// ----- shading (eval.h: exp2Poly, reflectance, shade) ---------------------------------------------------------------

float nradExp2(float x) {
    float xc = !(x > -125.0) ? -125.0 : (x > 125.0 ? 125.0 : x);
    float n = float(int(xc + (xc >= 0.0 ? 0.5 : -0.5)));
    return nradExpPolynomial((xc - n) * 0.693147181, n);
}

vec3 nradReflectance(NradSurface s, float cosNV) {
    const vec4 c0 = vec4(-1.0, -0.0275, -0.572, 0.022), c1 = vec4(1.0, 0.0425, 1.04, -0.04);
    float rough = s.roughness < 0.0 ? 0.0 : (s.roughness > 1.0 ? 1.0 : s.roughness);
    float m = s.metallic < 0.0 ? 0.0 : (s.metallic > 1.0 ? 1.0 : s.metallic);
    float nv = cosNV > 0.0 ? (cosNV < 1.0 ? cosNV : 1.0) : 0.0;
    vec4 r = rough * c0 + c1;
    float a004 = min(r.x * r.x, nradExp2(-9.28 * nv)) * r.x + r.y;
    float A = max(0.0, -1.04 * a004 + r.z), B = max(0.0, 1.04 * a004 + r.w);
    float w = s.specular * (1.0 - m) + m;
    vec3 out_;
    for (int c = 0; c < 3; ++c) {
        float base = s.baseColor[c] > 0.0 ? (s.baseColor[c] < 1.0 ? s.baseColor[c] : 1.0) : 0.0;
        float f0 = 0.04 * s.specular * (1.0 - m) + base * m;
        float v = base * (1.0 - m) + f0 * A + w * B;
        out_[c] = v > 0.0 ? v : 0.0;
    }
    return out_;
}

uint nradShade(vec3 position, vec3 normal, vec3 direction, NradSurface surface, out vec3 radiance) {
    vec3 stored;
    uint flags = nradEvaluate(position, normal, direction, stored);
    uint content = nradContentFlags();
    float cosNV = dot(normal, direction);
    vec3 r = (content & NRAD_CONTENT_DEMODULATED) != 0u ? nradReflectance(surface, nradFinite(cosNV) ? cosNV : 0.0) : vec3(1.0, 1.0, 1.0);
    vec3 e = vec3(0.0, 0.0, 0.0);
    if ((content & NRAD_CONTENT_SCATTERED_RADIANCE) != 0u)
        for (int c = 0; c < 3; ++c) e[c] = nradFinite(surface.emission[c]) ? surface.emission[c] : 0.0;
    radiance = r * stored + e;
    for (int c = 0; c < 3; ++c) radiance[c] = nradFinite(radiance[c]) ? radiance[c] : 0.0;
    return flags;
}

// A receiver that was not in the bake (eval.h: shadeVolume): its reflectance times the volume's light, plus its
// emission, towards the viewer.
uint nradShadeVolume(vec3 position, vec3 normal, vec3 direction, NradSurface surface, out vec3 radiance) {
    vec3 stored;
    uint flags = nradEvaluateVolume(position, normal, stored);
    float cosNV = dot(normal, direction);
    vec3 r = nradReflectance(surface, nradFinite(cosNV) ? cosNV : 0.0);
    vec3 e = vec3(0.0, 0.0, 0.0);
    for (int c = 0; c < 3; ++c) e[c] = nradFinite(surface.emission[c]) ? surface.emission[c] : 0.0;
    radiance = r * stored + e;
    for (int c = 0; c < 3; ++c) radiance[c] = nradFinite(radiance[c]) ? radiance[c] : 0.0;
    return flags;
}

#endif  // NRAD_GLSL
