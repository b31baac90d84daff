// nrad.hpp: a header-only C++ wrapper over nrad.h. Move-only RAII handle; nothing throws (engines often
// build with -fno-exceptions): failures come back as NradStatus.
#pragma once

#include <cstddef>
#include <cstdint>
#include <string>
#include <utility>

#include "nrad/nrad.h"

namespace nrad {

class Asset {
public:
    Asset() = default;
    ~Asset() { nradReleaseAsset(handle_); }
    Asset(Asset&& o) noexcept : handle_(std::exchange(o.handle_, nullptr)) {}
    Asset& operator=(Asset&& o) noexcept {
        if (this != &o) {
            nradReleaseAsset(handle_);
            handle_ = std::exchange(o.handle_, nullptr);
        }
        return *this;
    }
    Asset(const Asset&) = delete;
    Asset& operator=(const Asset&) = delete;

    // Replaces the held asset. On failure the wrapper is empty and `message` (if given) says why.
    NradStatus loadFromFile(const char* path, std::string* message = nullptr) {
        reset();
        char buf[256];
        NradStatus s = nradLoadFromFile(path, &handle_, buf, sizeof buf);
        if (message) *message = buf;
        return s;
    }
    NradStatus loadFromMemory(const void* data, size_t size, NradLoadFlags flags = NRAD_LOAD_COPY,
                              std::string* message = nullptr) {
        reset();
        char buf[256];
        NradStatus s = nradLoadFromMemory(data, size, uint32_t(flags), &handle_, buf, sizeof buf);
        if (message) *message = buf;
        return s;
    }
    void reset() {
        nradReleaseAsset(handle_);
        handle_ = nullptr;
    }

    explicit operator bool() const { return handle_ != nullptr; }
    NradAsset get() const { return handle_; }

    NradStatus info(NradAssetInfo& out) const { return nradGetAssetInfo(handle_, &out); }
    NradStatus evaluate(const float position[3], const float normal[3], const float direction[3], float rgb[3],
                        uint32_t* flags = nullptr) const {
        return nradEvaluate(handle_, position, normal, direction, rgb, flags);
    }
    NradStatus evaluateBatch(size_t count, const float* positions, const float* normals, const float* directions, float* rgb,
                             uint8_t* flags = nullptr) const {
        return nradEvaluateBatch(handle_, count, positions, normals, directions, rgb, flags);
    }
    NradStatus evaluateBatch(size_t count, const NradBatchSoA& batch) const {
        return nradEvaluateBatchSoA(handle_, count, &batch);
    }
    // The light in the volume (nradEvaluateVolumeBatch): E(x, n) / pi for receivers not in the bake.
    NradStatus evaluateVolumeBatch(size_t count, const float* positions, const float* normals, float* rgb,
                                   uint8_t* flags = nullptr) const {
        return nradEvaluateVolumeBatch(handle_, count, positions, normals, rgb, flags);
    }
    // Its glossy response (nradEvaluateVolumeGlossyBatch): the light prefiltered by a lobe of roughness 0.3.
    NradStatus evaluateVolumeGlossyBatch(size_t count, const float* positions, const float* normals, const float* viewDirections,
                                         float* rgb, uint8_t* flags = nullptr) const {
        return nradEvaluateVolumeGlossyBatch(handle_, count, positions, normals, viewDirections, rgb, flags);
    }
    NradStatus shadeBatch(size_t count, const float* positions, const float* normals, const float* directions,
                          const NradSurface* surfaces, float* rgb, uint8_t* flags = nullptr) const {
        return nradShadeBatch(handle_, count, positions, normals, directions, surfaces, rgb, flags);
    }
    // The packed GPU buffer (nradGetGpuBufferSize / nradPackGpuBuffer): `bytes` of 4-byte-aligned `buffer`.
    NradStatus gpuBufferSize(size_t& bytes) const { return nradGetGpuBufferSize(handle_, &bytes); }
    NradStatus packGpuBuffer(void* buffer, size_t capacity) const { return nradPackGpuBuffer(handle_, buffer, capacity); }

private:
    NradAsset handle_ = nullptr;
};

}  // namespace nrad
