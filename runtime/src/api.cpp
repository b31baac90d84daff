// The C API (nrad.h): every nrad* entry point, each checking its arguments and catching everything, so that
// nothing crosses the C boundary; the work is done in the files named after it.
#include <cstring>
#include <fstream>
#include <iterator>
#include <new>
#include <string>
#include <vector>

#include <nrad/format.h>
#include <nrad/nrad.h>

#include "asset.h"
#include "asset_loading.h"
#include "evaluation.h"
#include "gbuffer.h"
#include "gpu_buffer.h"
#include "kernel_dispatch.h"

using namespace nrad;

// NradAssetInfo.contentFlags hands the header's flags through: the C API's names for the same bits.
static_assert(NRAD_CONTENT_SCATTERED_RADIANCE == format::kFlagScatteredRadiance, "content flag bits");
static_assert(NRAD_CONTENT_DEMODULATED == format::kFlagDemodulated, "content flag bits");
static_assert(NRAD_CONTENT_BLENDED == format::kFlagBlended, "content flag bits");
static_assert(NRAD_CONTENT_TREE == format::kFlagTree, "content flag bits");
static_assert(rt::kContentScattered == format::kFlagScatteredRadiance && rt::kContentDemodulated == format::kFlagDemodulated,
              "content flag bits");
static_assert(sizeof(NradSurface) == 9 * sizeof(float), "rt::GBufferIo reads surfaces as nine floats");

namespace {

template <typename F>
NradStatus guarded(F&& f) {
    try {
        return f();
    } catch (const std::bad_alloc&) {
        return NRAD_ERROR_OUT_OF_MEMORY;
    } catch (...) {
        return NRAD_ERROR_INTERNAL;
    }
}

}  // namespace

extern "C" {

uint32_t nradGetVersion(void) { return NRAD_VERSION; }

const char* nradStatusString(NradStatus status) {
    switch (status) {
        case NRAD_OK: return "ok";
        case NRAD_ERROR_INVALID_ARGUMENT: return "invalid argument";
        case NRAD_ERROR_OUT_OF_MEMORY: return "out of memory";
        case NRAD_ERROR_IO: return "the file could not be read";
        case NRAD_ERROR_TRUNCATED: return "the asset is truncated";
        case NRAD_ERROR_NOT_AN_ASSET: return "not an .nrad asset";
        case NRAD_ERROR_UNSUPPORTED_VERSION: return "unsupported asset format version";
        case NRAD_ERROR_CORRUPT: return "the asset is damaged (checksum or structure)";
        case NRAD_ERROR_INVALID_CONTENT: return "the asset's content is invalid";
        case NRAD_ERROR_UNSUPPORTED_KERNEL: return "this CPU cannot run the requested kernel";
        case NRAD_ERROR_INTERNAL: return "internal error";
        case NRAD_ERROR_UNSUPPORTED_GPU_LAYOUT: return "the asset exceeds the GPU layout's limits";
    }
    return "unknown status";
}

NradStatus nradLoadFromMemory(const void* data, size_t size, uint32_t flags, NradAsset* asset, char* message,
                              size_t messageSize) {
    return guarded([&] { return rt::loadAsset(data, size, flags, asset, message, messageSize); });
}

NradStatus nradLoadFromFile(const char* path, NradAsset* asset, char* message, size_t messageSize) {
    return guarded([&] {
        if (!path || !asset) return NRAD_ERROR_INVALID_ARGUMENT;
        *asset = nullptr;
        std::ifstream f(path, std::ios::binary);
        if (!f) {
            rt::writeMessage(message, messageSize, std::string(path) + ": cannot open file");
            return NRAD_ERROR_IO;
        }
        std::vector<char> bytes((std::istreambuf_iterator<char>(f)), std::istreambuf_iterator<char>());
        if (f.bad()) {
            rt::writeMessage(message, messageSize, std::string(path) + ": read error");
            return NRAD_ERROR_IO;
        }
        NradStatus st = rt::loadAsset(bytes.data(), bytes.size(), NRAD_LOAD_COPY, asset, message, messageSize);
        if (st != NRAD_OK && message && messageSize > 0) {
            std::string m = std::string(path) + ": " + message;
            rt::writeMessage(message, messageSize, m);
        }
        return st;
    });
}

void nradReleaseAsset(NradAsset asset) { delete asset; }

NradStatus nradGetAssetInfo(NradAsset a, NradAssetInfo* info) {
    if (!a || !info) return NRAD_ERROR_INVALID_ARGUMENT;
    return guarded([&] {
        NradAssetInfo r;
        std::memset(&r, 0, sizeof r);
        r.formatVersionMajor = a->asset.header.versionMajor;
        r.formatVersionMinor = a->asset.header.versionMinor;
        for (int k = 0; k < 3; ++k) {
            r.gridLower[k] = a->asset.grid.lower[k];
            r.gridUpper[k] = a->asset.grid.upper[k];
            r.gridDims[k] = a->asset.grid.dims[k];
        }
        const format::Topology& t = a->asset.topology;
        r.occupiedVoxels = uint32_t(a->asset.voxels.size());
        r.inputs = t.inputs;
        r.outputs = t.outputs;
        r.hiddenLayers = uint32_t(t.hiddenWidths.size());
        for (size_t l = 0; l < t.hiddenWidths.size() && l < NRAD_MAX_HIDDEN_LAYERS; ++l) r.hiddenWidths[l] = t.hiddenWidths[l];
        r.parametersPerNetwork = a->paramsPerNetwork;
        r.weightEncoding = uint32_t(t.weightEncoding);
        r.outputTransform = uint32_t(t.outputTransform);
        r.contentFlags = a->asset.header.flags & format::kKnownFlags;  // NRAD_CONTENT_* are the header's flags
        r.blendBand = a->partition.band;
        r.fileBytes = a->fileBytes;
        // The handle's tables and weights, the volume's and its glossy response's (assets of their own) included.
        auto heldBytes = [](const NradAsset_& x) {
            return sizeof(NradAsset_) + x.asset.weights.size() * sizeof(float) +
                   x.asset.voxels.size() * (sizeof(format::VoxelEntry) + sizeof(float)) + x.denseLookup.size() * sizeof(int32_t) +
                   x.partition.bytes() + x.metadataCopy.size();
        };
        r.memoryBytes = heldBytes(*a);
        if (a->volume) {
            r.volumeNetworks = uint32_t(a->volume->asset.voxels.size());
            r.memoryBytes += heldBytes(*a->volume);
        }
        if (a->glossy) {
            r.glossyNetworks = uint32_t(a->glossy->asset.voxels.size());
            r.memoryBytes += heldBytes(*a->glossy);
        }
        *info = r;
        return NRAD_OK;
    });
}

NradStatus nradGetOccupiedVoxel(NradAsset a, uint32_t i, uint32_t* voxelIndex) {
    if (!a || !voxelIndex || i >= a->asset.voxels.size()) return NRAD_ERROR_INVALID_ARGUMENT;
    *voxelIndex = a->asset.voxels[i].index;
    return NRAD_OK;
}

NradStatus nradGetMetadata(NradAsset a, const char** json, size_t* length) {
    if (!a || !json || !length) return NRAD_ERROR_INVALID_ARGUMENT;
    *json = a->metadataLength ? a->metadata : "";
    *length = a->metadataLength;
    return NRAD_OK;
}

NradStatus nradEvaluate(NradAsset a, const float position[3], const float normal[3], const float direction[3], float rgb[3],
                        uint32_t* pointFlags) {
    if (!a || !position || !normal || !direction || !rgb) return NRAD_ERROR_INVALID_ARGUMENT;
    return guarded([&] {
        uint8_t flag = 0;
        rt::BatchIo v{{position, position + 1, position + 2}, {normal, normal + 1, normal + 2},
                      {direction, direction + 1, direction + 2}, {rgb, rgb + 1, rgb + 2}, 3, &flag, nullptr};
        NradStatus st = rt::evaluateBatch(*a, 1, v);
        if (pointFlags) *pointFlags = flag;
        return st;
    });
}

NradStatus nradEvaluateBatch(NradAsset a, size_t count, const float* positions, const float* normals,
                             const float* directions, float* rgb, uint8_t* pointFlags) {
    if (!a || (count > 0 && (!positions || !normals || !directions || !rgb))) return NRAD_ERROR_INVALID_ARGUMENT;
    if (count == 0) return NRAD_OK;
    return guarded([&] {
        rt::BatchIo v{{positions, positions + 1, positions + 2}, {normals, normals + 1, normals + 2},
                      {directions, directions + 1, directions + 2}, {rgb, rgb + 1, rgb + 2}, 3, pointFlags, nullptr};
        return rt::evaluateBatch(*a, count, v);
    });
}

NradStatus nradEvaluateVolumeBatch(NradAsset a, size_t count, const float* positions, const float* normals, float* rgb,
                                   uint8_t* pointFlags) {
    if (!a || !a->volume || (count > 0 && (!positions || !normals || !rgb))) return NRAD_ERROR_INVALID_ARGUMENT;
    if (count == 0) return NRAD_OK;
    return guarded([&] {
        // The volume's networks take the normal as the direction too (what they were trained with).
        rt::BatchIo v{{positions, positions + 1, positions + 2}, {normals, normals + 1, normals + 2},
                      {normals, normals + 1, normals + 2}, {rgb, rgb + 1, rgb + 2}, 3, pointFlags, nullptr};
        return rt::evaluateBatch(*a->volume, count, v);
    });
}

NradStatus nradEvaluateVolumeGlossyBatch(NradAsset a, size_t count, const float* positions, const float* normals,
                                         const float* viewDirections, float* rgb, uint8_t* pointFlags) {
    if (!a || !a->glossy || (count > 0 && (!positions || !normals || !viewDirections || !rgb))) return NRAD_ERROR_INVALID_ARGUMENT;
    if (count == 0) return NRAD_OK;
    return guarded([&] {
        rt::BatchIo v{{positions, positions + 1, positions + 2}, {normals, normals + 1, normals + 2},
                      {viewDirections, viewDirections + 1, viewDirections + 2}, {rgb, rgb + 1, rgb + 2}, 3, pointFlags, nullptr};
        return rt::evaluateBatch(*a->glossy, count, v);
    });
}

NradStatus nradEvaluateBatchSoA(NradAsset a, size_t count, const NradBatchSoA* b) {
    if (!a || !b) return NRAD_ERROR_INVALID_ARGUMENT;
    if (count == 0) return NRAD_OK;
    if (!b->px || !b->py || !b->pz || !b->nx || !b->ny || !b->nz || !b->dx || !b->dy || !b->dz || !b->r || !b->g || !b->b)
        return NRAD_ERROR_INVALID_ARGUMENT;
    return guarded([&] {
        rt::BatchIo v{{b->px, b->py, b->pz}, {b->nx, b->ny, b->nz}, {b->dx, b->dy, b->dz}, {b->r, b->g, b->b}, 1, b->pointFlags, nullptr};
        return rt::evaluateBatch(*a, count, v);
    });
}

NradStatus nradShadeBatch(NradAsset a, size_t count, const float* positions, const float* normals, const float* directions,
                          const NradSurface* surfaces, float* rgb, uint8_t* pointFlags) {
    if (!a || (count > 0 && (!positions || !normals || !directions || !surfaces || !rgb))) return NRAD_ERROR_INVALID_ARGUMENT;
    if (count == 0) return NRAD_OK;
    return guarded([&] {
        // A G-buffer of the batch's arrays, its vectors as given: the vector kernels read, evaluate, shade and
        // write each coherent vector in registers (the bits of evaluating, then shadeOne per point).
        NradGBuffer g;
        std::memset(&g, 0, sizeof g);
        g.structSize = sizeof g;
        g.flags = NRAD_GBUFFER_UNIT_VECTORS;
        g.count = count;
        g.position = {positions, 3 * sizeof(float), NRAD_FORMAT_F32};
        g.normal = {normals, 3 * sizeof(float), NRAD_FORMAT_F32};
        g.direction = {directions, 3 * sizeof(float), NRAD_FORMAT_F32};
        g.surfaces = surfaces;
        g.pointFlags = pointFlags;
        g.output = rgb;
        g.outputFormat = NRAD_FORMAT_F32;
        g.outputChannels = 3;
        rt::shadeGBuffer(*a, g, rt::threadScratch());
        return NRAD_OK;
    });
}

NradStatus nradShadeGBuffer(NradAsset a, const NradGBuffer* g, void* scratch, size_t scratchBytes) {
    if (!a || !g || g->structSize != sizeof(NradGBuffer)) return NRAD_ERROR_INVALID_ARGUMENT;
    if (g->count == 0) return NRAD_OK;
    const bool eye = (g->flags & NRAD_GBUFFER_EYE) != 0, volume = (g->flags & NRAD_GBUFFER_VOLUME) != 0;
    auto valid = [](const NradAttribute& at) { return at.data && at.format <= NRAD_FORMAT_F16; };
    if ((g->flags & ~(NRAD_GBUFFER_EYE | NRAD_GBUFFER_UNIT_VECTORS | NRAD_GBUFFER_VOLUME)) || (volume && !a->volume) ||
        !valid(g->position) || !valid(g->normal) || (!eye && !(volume && !g->surfaces) && !valid(g->direction)) || !g->output || g->outputFormat > NRAD_FORMAT_F16 ||
        (g->outputChannels != 3 && g->outputChannels != 4) || (scratch && scratchBytes < rt::kScratchBytes + rt::kGBufferScratchBytes))
        return NRAD_ERROR_INVALID_ARGUMENT;
    return guarded([&] {
        rt::shadeGBuffer(*a, *g, scratch ? scratch : rt::threadScratch());
        return NRAD_OK;
    });
}

NradStatus nradGetGpuBufferSize(NradAsset a, size_t* bytes) {
    if (!a || !bytes) return NRAD_ERROR_INVALID_ARGUMENT;
    rt::GpuLayout l;
    NradStatus st = rt::gpuLayoutOf(*a, l);
    *bytes = st == NRAD_OK ? size_t(l.total) * 4 : 0;
    return st;
}

NradStatus nradPackGpuBuffer(NradAsset a, void* buffer, size_t capacity) {
    if (!a || !buffer) return NRAD_ERROR_INVALID_ARGUMENT;
    rt::GpuLayout l;
    if (NradStatus st = rt::gpuLayoutOf(*a, l); st != NRAD_OK) return st;
    if (capacity < l.total * 4) return NRAD_ERROR_INVALID_ARGUMENT;
    if (reinterpret_cast<uintptr_t>(buffer) % 4 != 0) return NRAD_ERROR_INVALID_ARGUMENT;
    rt::packGpuBuffer(*a, l, static_cast<uint32_t*>(buffer));
    return NRAD_OK;
}

void nradSetAllocator(NradAllocateFunction allocate, NradFreeFunction release, void* user) {
    rt::setScratchAllocator(allocate, release, user);
}

size_t nradGetScratchSize(void) { return rt::kScratchBytes + rt::kGBufferScratchBytes; }

NradStatus nradSelectKernel(NradKernel kernel) {
    if (kernel == NRAD_KERNEL_AUTO) {
        rt::setActiveKernel(rt::bestKernel());
        return NRAD_OK;
    }
    if (!rt::findKernel(kernel)) return NRAD_ERROR_INVALID_ARGUMENT;
    if (!rt::kernelSupported(kernel)) return NRAD_ERROR_UNSUPPORTED_KERNEL;
    rt::setActiveKernel(kernel);
    return NRAD_OK;
}

NradKernel nradActiveKernel(void) { return rt::activeKernel(); }

NradStatus nradSetAssetKernel(NradAsset a, NradKernel kernel) {
    if (!a || (kernel != NRAD_KERNEL_AUTO && !rt::findKernel(kernel))) return NRAD_ERROR_INVALID_ARGUMENT;
    if (kernel != NRAD_KERNEL_AUTO && !rt::kernelSupported(kernel)) return NRAD_ERROR_UNSUPPORTED_KERNEL;
    a->kernel.store(kernel, std::memory_order_relaxed);
    if (a->volume) a->volume->kernel.store(kernel, std::memory_order_relaxed);
    if (a->glossy) a->glossy->kernel.store(kernel, std::memory_order_relaxed);
    return NRAD_OK;
}

int nradKernelSupported(NradKernel kernel) { return kernel == NRAD_KERNEL_AUTO || rt::kernelSupported(kernel) ? 1 : 0; }

}  // extern "C"
