// Evaluation kernels: one network applied to a chunk of points in structure-of-arrays layout. Kept free of
// standard-library templates so the SIMD translation units share no inline code with the scalar ones.
#pragma once

#include <cstddef>
#include <cstdint>
#include <cstring>

#include <nrad/eval_constants.h>

#if defined(_MSC_VER) && !defined(__clang__)
#define NRAD_NOINLINE __declspec(noinline)
#define NRAD_ALWAYS_INLINE __forceinline
#else
#define NRAD_NOINLINE __attribute__((noinline))
#define NRAD_ALWAYS_INLINE __attribute__((always_inline))
#endif

namespace nrad::rt {

constexpr int kChunk = 64;  // points per chunk; the kernels process all of it (padding lanes are zeros)
constexpr int kMaxWidth = 256;
constexpr int kInputs = eval::kInputs;
constexpr int kOutputs = eval::kOutputs;

struct NetworkView {
    const float* params;  // per layer: W (out x in, row-major), b (out)
    uint32_t hiddenLayers;
    const uint32_t* hiddenWidths;
    float scale;  // the voxel's output scale
    bool exponential;  // output transform: scale (exp(y) - 1) instead of scale y; clamped at 0 either way
};

// exp(x) - 1 as nrad/eval.h defines it (eval::expMinusOne): x clamped to [kExpLo, kExpHi], range reduction
// and a degree-6 polynomial; the same constants in every kernel.
constexpr float kExpHi = eval::kMaxLog, kExpLo = eval::kMinLog, kLog2e = eval::kLog2e, kLn2Hi = eval::kLn2Hi, kLn2Lo = eval::kLn2Lo;
constexpr float kLn2 = eval::kLn2, kMaxExp2 = eval::kMaxExp2;
constexpr const float* kExpP = eval::kExpP;

// x: kInputs rows of kChunk floats; y: kOutputs rows of kChunk floats: the radiance (scale and output
// transform applied, clamped to [0, eval::kMaxRadiance], NaN mapped to 0) of the first `count` points (at most
// kChunk; vector kernels compute whole vectors, so rows must be readable, and are written, up to count
// rounded up to their width).
using ChunkKernel = void (*)(const NetworkView& net, const float* x, float* y, int count);

void evalChunkScalar(const NetworkView& net, const float* x, float* y, int count);
#if defined(__x86_64__) || defined(_M_X64)
void evalChunkAvx2(const NetworkView& net, const float* x, float* y, int count);
void evalChunkAvx512(const NetworkView& net, const float* x, float* y, int count);
#endif
#if defined(__aarch64__)
void evalChunkNeon(const NetworkView& net, const float* x, float* y, int count);
#endif

// fp16 <-> fp32 for G-buffers, n values: exactly format::halfToFloat / floatToHalf for the values these see
// (FloatToHalf's inputs are radiance: finite, >= 0; it saturates at 65504 as format::floatToHalf does).
using HalfToFloat = void (*)(const uint16_t* in, float* out, size_t n);
using FloatToHalf = void (*)(const float* in, uint16_t* out, size_t n);
void halfToFloatScalar(const uint16_t* in, float* out, size_t n);
void floatToHalfScalar(const float* in, uint16_t* out, size_t n);
#if defined(__x86_64__) || defined(_M_X64)
void halfToFloatF16c(const uint16_t* in, float* out, size_t n);  // AVX2 + F16C
void floatToHalfF16c(const float* in, uint16_t* out, size_t n);
#endif
#if defined(__aarch64__)
void halfToFloatNeon(const uint16_t* in, float* out, size_t n);
void floatToHalfNeon(const float* in, uint16_t* out, size_t n);
#endif

// ----- whole batches, a vector of points at a time (the SIMD kernels only) -----------------------------

// The grid as locate() in evaluation.cpp uses it; `dense` maps every voxel to its network or -1.
struct LocateGrid {
    float lower[3], upper[3];
    float factor[3];  // dims / (upper - lower)
    uint32_t dims[3];
    float band;  // blending band (eval::supports); 0: none
    const int32_t* dense;
};

// One G-buffer attribute of a tile as the block driver reads it: three fp32 or fp16 components per point,
// point i's at base + i stride.
struct StridedAttribute {
    const uint8_t* base;
    size_t stride;
    bool half;
};

// A tile of a G-buffer (nradShadeGBuffer) read and written by the block driver itself, so that a coherent
// vector of points goes from the caller's texels to the caller's pixels without leaving registers.
struct GBufferIo {
    StridedAttribute p, n, d;
    bool eye;  // directions eye - p (d unused); normalised
    float eyePosition[3];
    bool normaliseNormals;  // normals normalised on input
    bool normaliseDirections;  // directions normalised on input (always with eye)
    // Points [0, safePoints) may be read with a few bytes past their last component (one 16-byte load per
    // fp32 point, one 8-byte load per fp16 point): all but the G-buffer's last (last few, for strides under
    // 4 bytes).
    size_t safePoints;
    // Output pixels: `channels` (3 or 4; the fourth is 1) fp32 or fp16 values, `outStride` bytes apart. The
    // driver writes the pixels of the blocks it completes, marking their points in `done`, and fills
    // BatchIo::p/n/d (fp32, prepared) for the blocks it leaves to the other paths, whose pixels the caller
    // writes.
    uint8_t* out;
    size_t outStride;
    bool outHalf;
    int channels;
    uint8_t* done;  // per point, zeroed by the caller
    // The material terms (NradSurface's nine floats, `surfaceStride` bytes apart; null: none) the driver
    // shades its pixels with, by the asset's content flags (nrad/eval.h shade(), as gbuffer.cpp's
    // shadeOne applies it, bit for bit).
    const uint8_t* surfaces;
    size_t surfaceStride;
    uint32_t contentFlags;
};

// Where a batch's points come from and where their results go: interleaved (stride 3, the x pointers
// address the whole array) or SoA (stride 1, separate arrays). With `gbuffer`, the points come from there
// and p, n, d (interleaved, fp32) are where the driver leaves them, already normalised, for the other paths.
struct BatchIo {
    const float* p[3];
    const float* n[3];
    const float* d[3];
    float* out[3];
    size_t stride;
    uint8_t* flags;  // may be null
    const GBufferIo* gbuffer;  // may be null
};

// A kd-tree partition as the block driver locates whole vectors in it (the grid above holds the box, the
// lattice factors and, in `dense`, the leaf -> network table), built at load from eval::Partition (not part of
// the asset's contract: it finds the leaves eval::treeSupports finds). Node references are "tagged": an inner
// node's index, or -1 - leaf for a leaf, so that a descent ends on reaching a leaf without reading it.
// A vector whose points all lie in one leaf, away from every blending band, is evaluated in registers; any
// other is taken point by point (BlockDriver).
struct LocateTree {
    // Per node of the format's tree (leaves' entries unused), 3 words: its axis, its lower child and its upper
    // child, tagged; and its split, as a float.
    const int32_t* nodes;
    const float* splits;
    const int32_t* starts;  // eval::buildTreeStarts' table, tagged
    uint32_t startDims[3];
    float startScale[3];
    // Per leaf, 12 floats: the open box of lattice coordinates in which a point has this leaf alone with weight 1
    // (lo[3], hi[3]: inside the leaf and every ancestor's blending band, less a rounding margin), and the
    // leaf's lattice box as eval::localInBox takes it (float(lo)[3], float(hi - lo)[3]). Null: the grid.
    const float* leaves;
    // Small trees: the rectilinear grid of every split plane, a table that gives each point's leaf in two steps
    // (splits lie on the lattice, so a lattice voxel lies in one leaf and on one side of every plane). Per
    // lattice voxel along each axis, that axis's term of the cell index (axis 0 from rectAxis[0], axis 1 from
    // rectAxis[rectOffset[1]], axis 2 from rectAxis[rectOffset[2]]), summed; rectLeaves: each cell's leaf.
    // Null when the table would pass kMaxRectCells (then the start table and the descent).
    const int32_t* rectAxis;
    const int32_t* rectLeaves;
    uint32_t rectOffset[3];
    static constexpr size_t kMaxRectCells = size_t(1) << 16;
};

struct BlockContext {
    LocateGrid grid;
    LocateTree tree;
    NetworkView networks;  // of network 0; params advance by paramsPerNetwork per network
    uint32_t paramsPerNetwork;
    const float* scales;  // per network
    BatchIo io;
};

// What a block driver leaves to the grouped (sorted) pass.
struct Deferred {
    uint32_t* blocks;  // blocks with an invalid or outside point: located one point at a time
    size_t blockCount;
    uint32_t* points;  // single points left to the general path (in a band or an empty cell; the rest of their
                       // block was evaluated or recorded)
    size_t pointCount;
    uint32_t* index;  // points with one support recorded for the grouped pass: point, network, position input
    int32_t* network;
    float* local;  // 3 per point
    size_t count;
#ifdef NRAD_RUNTIME_TESTING  // the test build's counts of the paths blocks took (testing.h)
    size_t blendedBlocks = 0;  // blocks blended in registers (evalBlended)
    size_t gbufferBlocks = 0;  // G-buffer blocks whose pixels the driver wrote
    size_t treeBlocks = 0;  // blocks located in a kd-tree's leaf and evaluated in registers
#endif
};
// Counts one block in a Deferred's counter in the test build (testing.h); nothing in the shipped library.
#ifdef NRAD_RUNTIME_TESTING
#define NRAD_COUNT_FOR_TESTS(counter) (++(counter))
#else
#define NRAD_COUNT_FOR_TESTS(counter) ((void)0)
#endif

// The shading contract's flags (format::kFlagScatteredRadiance, format::kFlagDemodulated) as the kernels see them.
constexpr uint32_t kContentScattered = 1u, kContentDemodulated = 2u;

// Evaluates blocks [0, blocks) of `width` points each. A block with an invalid or outside point goes to
// def.blocks untouched. Any other is evaluated in vector registers with its results and flags written when
// it lies in one occupied cell outside every band (grid voxel or kd-tree leaf), or blends in registers (grids:
// at most kMaxBoxVoxels voxels); otherwise point by point: a point outside every band in an occupied cell
// joins def.index/network/local (one entry of weight 1, flag written), any other goes to def.points.
using BlockDriver = void (*)(const BlockContext& ctx, size_t blocks, Deferred& def);

#if defined(__x86_64__) || defined(_M_X64)
constexpr int kAvx2Width = 8, kAvx512Width = 16;
void evalBlocksAvx2(const BlockContext& ctx, size_t blocks, Deferred& def);
void evalBlocksAvx512(const BlockContext& ctx, size_t blocks, Deferred& def);
#endif
#if defined(__aarch64__)
constexpr int kNeonWidth = 4;
void evalBlocksNeon(const BlockContext& ctx, size_t blocks, Deferred& def);
#endif

}  // namespace nrad::rt
