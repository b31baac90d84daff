/* libnrad: load neural radiance assets (.nrad) and evaluate the radiance they store.
 *
 * The whole public C API (usable from C99 and C++). It depends on nothing but the C/C++ standard library.
 *
 * - Handles are opaque. Every function returns an NradStatus (or a plain value for simple queries) and
 *   never lets an exception or a signal escape; nradStatusString() describes each status.
 * - Loading is safe on untrusted input: every byte used is validated (magic, version, sizes and offsets
 *   against the buffer, counts, CRCs, finite weights). A damaged file gives a status, never undefined
 *   behaviour.
 * - Evaluation is thread-safe: any number of threads may evaluate the same asset concurrently. Loading and
 *   releasing are not concurrent with evaluation of the same handle.
 * - Radiance is in the scene's units (see the baker's docs/lights.md); directions point away from the
 *   surface, towards the viewer.
 * - What the networks store is in NradAssetInfo.contentFlags. With NRAD_CONTENT_SCATTERED_RADIANCE (every
 *   asset of format 2) the evaluation returns the radiance the surface *scatters*, without its own
 *   emission: the shader adds the surface's emissive term (material emission towards the viewer, textures
 *   included), as for any other surface (docs/runtime.md, "Shading contract").
 */
#ifndef NRAD_NRAD_H
#define NRAD_NRAD_H

#include <stddef.h>
#include <stdint.h>

#include "nrad/version.h"

#ifdef __cplusplus
extern "C" {
#endif

/* Exported symbols: only the functions below leave a shared libnrad (built with hidden visibility). Define
 * NRAD_SHARED when linking a shared build on Windows (the CMake package does it). */
#if defined(_WIN32)
#if defined(NRAD_BUILDING)
#define NRAD_API __declspec(dllexport)
#elif defined(NRAD_SHARED)
#define NRAD_API __declspec(dllimport)
#else
#define NRAD_API
#endif
#elif defined(__GNUC__) || defined(__clang__)
#define NRAD_API __attribute__((visibility("default")))
#else
#define NRAD_API
#endif

/* The library's version: NRAD_VERSION_MAJOR/MINOR/PATCH and NRAD_VERSION as compiled against;
 * nradGetVersion() as linked (major << 22 | minor << 12 | patch). Compatible within a minor version. */
NRAD_API uint32_t nradGetVersion(void);

typedef struct NradAsset_* NradAsset;

typedef enum NradStatus {
    NRAD_OK = 0,
    NRAD_ERROR_INVALID_ARGUMENT = 1,  /* a null pointer or a bad flag */
    NRAD_ERROR_OUT_OF_MEMORY = 2,
    NRAD_ERROR_IO = 3,                /* the file could not be opened or read */
    NRAD_ERROR_TRUNCATED = 4,         /* the data ends before a structure it announces */
    NRAD_ERROR_NOT_AN_ASSET = 5,      /* bad magic */
    NRAD_ERROR_UNSUPPORTED_VERSION = 6,
    NRAD_ERROR_CORRUPT = 7,           /* a CRC mismatch, trailing bytes, or an invalid section table */
    NRAD_ERROR_INVALID_CONTENT = 8,   /* a grid, topology, voxel table or weight that is not valid */
    NRAD_ERROR_UNSUPPORTED_KERNEL = 9,/* nradSelectKernel: this CPU cannot run that kernel */
    NRAD_ERROR_INTERNAL = 10,
    NRAD_ERROR_UNSUPPORTED_GPU_LAYOUT = 11 /* nradGetGpuBufferSize: the asset exceeds the GPU layout's limits */
} NradStatus;

/* A static, human-readable description of a status (never null). */
NRAD_API const char* nradStatusString(NradStatus status);

/* ----- loading --------------------------------------------------------------------------------------- */

typedef enum NradLoadFlags {
    NRAD_LOAD_COPY = 0,   /* the asset keeps its own copy; the caller's buffer may be freed after the call */
    NRAD_LOAD_BORROW = 1  /* the caller's buffer must stay alive and unchanged until nradReleaseAsset */
} NradLoadFlags;

/* Loads an asset from `size` bytes at `data`. On success *asset is a new handle; on failure it is null
 * and, if `message` is not null, up to `messageSize` bytes of an explanation are written there
 * (NUL-terminated). Safe on untrusted input. */
NRAD_API NradStatus nradLoadFromMemory(const void* data, size_t size, uint32_t flags, NradAsset* asset, char* message,
                              size_t messageSize);
/* Loads an asset from a file (read whole, then as nradLoadFromMemory with NRAD_LOAD_COPY). */
NRAD_API NradStatus nradLoadFromFile(const char* path, NradAsset* asset, char* message, size_t messageSize);
/* Releases a handle; null is allowed. */
NRAD_API void nradReleaseAsset(NradAsset asset);

/* ----- queries --------------------------------------------------------------------------------------- */

#define NRAD_MAX_HIDDEN_LAYERS 8

typedef struct NradAssetInfo {
    uint32_t formatVersionMajor, formatVersionMinor;
    float gridLower[3], gridUpper[3];
    uint32_t gridDims[3];
    uint32_t occupiedVoxels;
    uint32_t inputs, outputs;
    uint32_t hiddenLayers;
    uint32_t hiddenWidths[NRAD_MAX_HIDDEN_LAYERS];
    uint32_t parametersPerNetwork;
    uint32_t weightEncoding;   /* 0 = fp32, 1 = fp16 (as stored in the file) */
    uint32_t outputTransform;  /* 0 = scale max(0, y), 1 = scale (exp(y) - 1): the surfaces' (the volume's networks
                                  decode exponentially where format 2.6's volume flag says so; the runtime applies it) */
    uint32_t contentFlags;     /* NRAD_CONTENT_*: what the networks store */
    float blendBand;           /* with NRAD_CONTENT_BLENDED: half-width of the blending band, in voxels; else 0 */
    uint64_t fileBytes;        /* size of the asset data */
    uint64_t memoryBytes;      /* memory held by the handle */
    uint32_t volumeNetworks;   /* networks of the light in the volume (nradEvaluateVolumeBatch); 0: none (format 2.4) */
    uint32_t glossyNetworks;   /* networks of its glossy response (nradEvaluateVolumeGlossyBatch); 0: none (format 2.5) */
    uint32_t reserved[14];     /* zero; later minor versions add fields here, so the struct keeps its size */
} NradAssetInfo;

/* contentFlags: the radiance returned excludes the surface's own emission (add it when shading). */
#define NRAD_CONTENT_SCATTERED_RADIANCE 1u
/* contentFlags: the radiance returned is divided by the surface's reflectance (multiply it back when shading:
 * nradShadeBatch does both). */
#define NRAD_CONTENT_DEMODULATED 2u
/* contentFlags: points within blendBand voxels of an interior voxel face are shaded by the networks on both
 * sides, blended continuously (docs/format.md, "Blended supports"); up to 8 evaluations per point. */
#define NRAD_CONTENT_BLENDED 4u
/* contentFlags: the grid is the lattice of an adaptive kd-tree partition (format 2.2): occupiedVoxels counts
 * the networks of its leaves, nradGetOccupiedVoxel returns leaf indices (docs/format.md, "Partition tree"). */
#define NRAD_CONTENT_TREE 8u

NRAD_API NradStatus nradGetAssetInfo(NradAsset asset, NradAssetInfo* info);
/* Index (x + dims[0] (y + dims[1] z)) of the i-th occupied voxel, i < occupiedVoxels (with NRAD_CONTENT_TREE:
 * the index of its tree leaf). */
NRAD_API NradStatus nradGetOccupiedVoxel(NradAsset asset, uint32_t i, uint32_t* voxelIndex);
/* The metadata JSON (not NUL-terminated) and its length; empty if the asset has none. Valid while the
 * handle lives. */
NRAD_API NradStatus nradGetMetadata(NradAsset asset, const char** json, size_t* length);

/* ----- evaluation ------------------------------------------------------------------------------------ */

/* Per-point result flags. */
enum {
    NRAD_POINT_OK = 0,
    NRAD_POINT_OUTSIDE_GRID = 1,   /* the position is outside the asset's grid: radiance 0 */
    NRAD_POINT_EMPTY_VOXEL = 2,    /* no network shades the point (its voxel has none, and with
                                      NRAD_CONTENT_BLENDED no neighbour it blends with has one): radiance 0 */
    NRAD_POINT_INVALID_INPUT = 4   /* a non-finite input value: radiance 0 */
};

/* Radiance leaving `position` (world space) with shading normal `normal` towards `direction` (both unit
 * length, pointing away from the surface). Writes rgb[3]; `pointFlags` may be null. */
NRAD_API NradStatus nradEvaluate(NradAsset asset, const float position[3], const float normal[3], const float direction[3],
                        float rgb[3], uint32_t* pointFlags);

/* Batch, interleaved layout: positions, normals, directions and rgb are `count` x 3 floats (x, y, z, ...).
 * `pointFlags` (count bytes) may be null. Points are grouped by voxel internally where that is faster. */
NRAD_API NradStatus nradEvaluateBatch(NradAsset asset, size_t count, const float* positions, const float* normals,
                             const float* directions, float* rgb, uint8_t* pointFlags);

/* Batch, structure-of-arrays layout: each pointer is `count` floats. */
typedef struct NradBatchSoA {
    const float* px; const float* py; const float* pz;
    const float* nx; const float* ny; const float* nz;
    const float* dx; const float* dy; const float* dz;
    float* r; float* g; float* b;
    uint8_t* pointFlags; /* may be null */
} NradBatchSoA;
NRAD_API NradStatus nradEvaluateBatchSoA(NradAsset asset, size_t count, const NradBatchSoA* batch);

/* The light in the volume, for receivers that were not in the bake (moving objects; assets baked with
 * `nrad bake --volume-points`): per point (world space, anywhere in the grid) and unit normal, the radiance a
 * white Lambertian receiver there facing the normal scatters, E(x, n) / pi (E: the irradiance on a plane through
 * x facing n, from everything the asset holds: engine-drawn direct light excluded, as on the surfaces). A diffuse
 * receiver of albedo a reflects a times it. Interleaved layout as nradEvaluateBatch; point flags as there.
 * NRAD_ERROR_INVALID_ARGUMENT for an asset without volume networks (NradAssetInfo::volumeNetworks 0). */
NRAD_API NradStatus nradEvaluateVolumeBatch(NradAsset asset, size_t count, const float* positions, const float* normals,
                                            float* rgb, uint8_t* pointFlags);

/* The volume's glossy response (assets baked with `nrad bake --volume-points N --volume-glossy`): per point, unit
 * normal and unit direction towards the viewer (in the normal's hemisphere), the light arriving at the point
 * prefiltered by a GGX lobe of roughness 0.3 (eval::kGlossyRoughness): what a white metallic receiver of that
 * roughness reflects towards the viewer, over that lobe's split-sum albedo. nrad/eval.h's shadeVolumeGlossy
 * combines it with nradEvaluateVolumeBatch's value and the receiver's material. Layout and flags as
 * nradEvaluateBatch; NRAD_ERROR_INVALID_ARGUMENT for an asset without it (NradAssetInfo::glossyNetworks 0). */
NRAD_API NradStatus nradEvaluateVolumeGlossyBatch(NradAsset asset, size_t count, const float* positions, const float* normals,
                                                  const float* viewDirections, float* rgb, uint8_t* pointFlags);

/* ----- shading --------------------------------------------------------------------------------------- */

/* The material terms a G-buffer holds at a pixel: base colour (linear, textures applied), metallic, roughness
 * (perceptual), the KHR_materials_specular factor (1 if the material has none), and the radiance the surface
 * emits towards the viewer. */
typedef struct NradSurface {
    float baseColor[3];
    float metallic;
    float roughness;
    float specular;
    float emission[3];
} NradSurface;

/* The final radiance leaving each point towards the viewer: the asset's evaluation recombined with the
 * surface's material by the asset's contract (docs/runtime.md, "Shading contract"): multiplied by the
 * reflectance if the asset is demodulated, plus the emission if it stores scattered radiance. Arguments as
 * nradEvaluateBatch, and `surfaces` (count). A point outside the grid or in an empty voxel gets its emission
 * only (and its flag). */
NRAD_API NradStatus nradShadeBatch(NradAsset asset, size_t count, const float* positions, const float* normals,
                          const float* directions, const NradSurface* surfaces, float* rgb, uint8_t* pointFlags);

/* ----- memory ------------------------------------------------------------------------------------------ */

/* Evaluation allocates nothing once a thread has its scratch: a block of nradGetScratchSize() bytes, either
 * passed by the caller (nradShadeGBuffer) or allocated once per thread, on the thread's first evaluation,
 * through the allocator below (malloc/free by default) and released when the thread ends. Loading an asset
 * allocates through the C++ standard library. */
typedef void* (*NradAllocateFunction)(size_t bytes, void* user);
typedef void (*NradFreeFunction)(void* memory, void* user);
/* Sets the allocator for per-thread scratch (null functions restore malloc/free). Not concurrent with
 * evaluation. A thread's block is released, when the thread ends, through the function and `user` it was
 * allocated with: they must stay valid until every thread that evaluated with them has ended. */
NRAD_API void nradSetAllocator(NradAllocateFunction allocate, NradFreeFunction release, void* user);
/* Bytes of scratch any evaluation call needs, whatever the batch size or asset (evaluation works in tiles of
 * 1,024 points); nradShadeGBuffer takes it from the caller. */
NRAD_API size_t nradGetScratchSize(void);

/* ----- GPU buffers -------------------------------------------------------------------------------------- */

/* The asset packed for shading on a GPU: one buffer of little-endian 32-bit words that an engine uploads as a
 * read-only storage buffer (Vulkan, D3D12 structured/raw buffer, OpenGL SSBO, Metal buffer) and that
 * runtime/shaders/nrad.glsl reads: a 256-byte header of constants and word offsets, the cell -> network table,
 * the networks' output scales, the kd-tree (nodes, blending widths, leaf boxes) if the asset has one, and the
 * weights in fp16, two per word (docs/runtime.md, "GPU buffers"). Built from the loaded, validated asset: the
 * loader's checks apply unchanged. fp16 weights are copied exactly; fp32 weights are rounded to fp16. */
#define NRAD_GPU_LAYOUT_VERSION 2  /* 2: the volume's own output transform (word 41) */
/* The widest hidden layer the GLSL evaluates (its per-invocation arrays); wider assets cannot be packed. */
#define NRAD_GPU_MAX_HIDDEN_WIDTH 32
/* The largest cell -> network table packed (cells: grid voxels, or tree leaves); larger assets cannot be. */
#define NRAD_GPU_MAX_CELLS (1u << 24)

/* Bytes of the packed buffer (a multiple of 4). NRAD_ERROR_UNSUPPORTED_GPU_LAYOUT if the asset exceeds the
 * limits above. */
NRAD_API NradStatus nradGetGpuBufferSize(NradAsset asset, size_t* bytes);
/* Writes the packed buffer to `buffer` (4-byte aligned, at least nradGetGpuBufferSize bytes: a mapped
 * staging buffer will do); writes nothing and returns NRAD_ERROR_INVALID_ARGUMENT if `capacity` is smaller or
 * `buffer` is not aligned. Allocates nothing. */
NRAD_API NradStatus nradPackGpuBuffer(NradAsset asset, void* buffer, size_t capacity);

/* ----- G-buffers --------------------------------------------------------------------------------------- */

/* What a G-buffer's channels hold, read as they are: fp32 or fp16 (IEEE binary16) values. */
typedef enum NradFormat { NRAD_FORMAT_F32 = 0, NRAD_FORMAT_F16 = 1 } NradFormat;

/* Three values per point (x, y, z) in `format`, point i at (const char*)data + i * stride. */
typedef struct NradAttribute {
    const void* data;
    size_t stride;   /* bytes from one point to the next; 0: tightly packed (12 bytes fp32, 6 fp16) */
    uint32_t format; /* NradFormat */
} NradAttribute;

#define NRAD_GBUFFER_EYE 1u          /* directions from `eye`: normalize(eye - position); `direction` unused */
#define NRAD_GBUFFER_UNIT_VECTORS 2u /* normals and directions are unit length already: not normalised */
/* The points are receivers that were not in the bake (moving objects): the asset's volume query at each position
 * and normal (nradEvaluateVolumeBatch; the asset must have volume networks, else NRAD_ERROR_INVALID_ARGUMENT), and
 * with `surfaces` the receiver's radiance towards the viewer by nrad/eval.h's shadeVolume: its reflectance times
 * the query plus its emission. `direction` (or `eye`) is read only for shading: evaluate-only may leave it null. */
#define NRAD_GBUFFER_VOLUME 4u

/* A G-buffer (or any batch of surface points) as an engine holds it. Normals and directions are normalised on
 * input unless NRAD_GBUFFER_UNIT_VECTORS; a zero or non-finite one makes the point NRAD_POINT_INVALID_INPUT. */
typedef struct NradGBuffer {
    uint32_t structSize;          /* sizeof(NradGBuffer) of the header compiled against */
    uint32_t flags;               /* NRAD_GBUFFER_* */
    size_t count;                 /* points */
    NradAttribute position;       /* world space */
    NradAttribute normal;         /* shading normal, on the viewer's side */
    NradAttribute direction;      /* towards the viewer (unused with NRAD_GBUFFER_EYE) */
    float eye[3];                 /* the camera position, with NRAD_GBUFFER_EYE */
    const NradSurface* surfaces;  /* null: the output is what the asset stores (nradEvaluateBatch); else the shaded
                                     radiance (nradShadeBatch) from these material terms */
    size_t surfaceStride;         /* bytes from one surface to the next; 0: sizeof(NradSurface) */
    void* output;                 /* RGB or RGBA (alpha 1) per point */
    size_t outputStride;          /* bytes; 0: tightly packed */
    uint32_t outputFormat;        /* NradFormat: fp16 rounds to nearest even and saturates at 65504 */
    uint32_t outputChannels;      /* 3 or 4 */
    uint8_t* pointFlags;          /* NRAD_POINT_* per point; may be null */
} NradGBuffer;

/* Evaluates or shades a G-buffer. `scratch` (at least nradGetScratchSize() bytes, any alignment) makes the
 * call allocate nothing at all; null uses the calling thread's scratch. Results equal nradEvaluateBatch /
 * nradShadeBatch on the same values converted to fp32, bit for bit before the output's own rounding. */
NRAD_API NradStatus nradShadeGBuffer(NradAsset asset, const NradGBuffer* gbuffer, void* scratch, size_t scratchBytes);

/* ----- kernels --------------------------------------------------------------------------------------- */

typedef enum NradKernel {
    NRAD_KERNEL_AUTO = 0,    /* the fastest this CPU supports (the default) */
    NRAD_KERNEL_SCALAR = 1,  /* plain C++, any CPU: the reference */
    NRAD_KERNEL_AVX2 = 2,    /* x86-64 with AVX2 and FMA */
    NRAD_KERNEL_AVX512 = 3,  /* x86-64 with AVX-512F */
    NRAD_KERNEL_NEON = 4     /* 64-bit ARM (Advanced SIMD) */
} NradKernel;

/* Chooses the evaluation kernel for this process (for testing and measurement). Fails with
 * NRAD_ERROR_UNSUPPORTED_KERNEL if this CPU cannot run it. Not concurrent with evaluation. */
NRAD_API NradStatus nradSelectKernel(NradKernel kernel);
/* The kernel evaluation uses now (never NRAD_KERNEL_AUTO). */
NRAD_API NradKernel nradActiveKernel(void);
/* The kernel for one asset's evaluations, whatever the process-wide choice (NRAD_KERNEL_AUTO: follow it).
 * Safe while other threads evaluate the asset. */
NRAD_API NradStatus nradSetAssetKernel(NradAsset asset, NradKernel kernel);
/* Nonzero if this CPU and build can run `kernel`. */
NRAD_API int nradKernelSupported(NradKernel kernel);

#ifdef __cplusplus
}
#endif

#endif /* NRAD_NRAD_H */
