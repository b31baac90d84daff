// Fuzz target for the runtime: load arbitrary bytes (copying and borrowing); if they load, query the asset
// and evaluate points derived from the input, single and batched, in both layouts, through every kernel this
// CPU runs, with inputs up to 1e38 in magnitude, as a G-buffer (fp16 attributes, shaded) and packed for the
// GPU. Any crash, sanitizer report or non-finite radiance is a bug. Partition trees are also built straight
// from the input's bytes with valid CRCs (fuzzTree), so mutations reach the tree's validation; and with
// NRAD_FUZZ_CUSTOM_MUTATOR (the libFuzzer build) three of four mutations have their CRCs recomputed
// (crc_fixup.h), so they reach the decoder's checks past the CRCs. Built by tests/fuzz/CMakeLists.txt (clang,
// libFuzzer, ASan, UBSan).
#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <cstring>
#include <vector>

#include <nrad/format.h>
#include <nrad/nrad.h>

#include "crc_fixup.h"

namespace {

// Partition trees past the CRCs (format 2.2): the input's bytes read as TREE nodes of a 16^3 lattice,
// wrapped in an asset whose CRCs hold, so every mutation reaches the tree's validation; what loads is
// evaluated over the whole lattice and must give finite, non-negative radiance.
void fuzzTree(const uint8_t* data, size_t size) {
    if (size < 9) return;
    nrad::format::Asset a;
    for (int k = 0; k < 3; ++k) {
        a.grid.lower[k] = 0.0f;
        a.grid.upper[k] = 1.0f;
        a.grid.dims[k] = 16;
    }
    a.header.flags = nrad::format::kFlagScatteredRadiance | nrad::format::kFlagTree;
    if (data[0] & 1) {
        a.header.flags |= nrad::format::kFlagBlended;
        a.grid.blendBand = 0.5f * float(1 + (data[0] >> 1)) / 128.0f;
    }
    a.topology.hiddenWidths = {2};
    for (size_t at = 1; at + 8 <= size && a.tree.size() < 4096; at += 8) {
        uint32_t word, child;
        std::memcpy(&word, data + at, 4);
        std::memcpy(&child, data + at + 4, 4);
        a.tree.push_back({word & 3u, word >> 2, child & ~nrad::format::kTreeHardBit, (child & nrad::format::kTreeHardBit) != 0});
    }
    a.voxels = {{0, 1.0f}};
    a.weights.assign(a.topology.parameterCount(), 0.25f);
    const std::vector<uint8_t> bytes = nrad::format::encodeUnchecked(a);  // the tree is the fuzzer's: invalid on purpose
    NradAsset asset = nullptr;
    if (nradLoadFromMemory(bytes.data(), bytes.size(), NRAD_LOAD_COPY, &asset, nullptr, 0) != NRAD_OK) {
        if (asset) std::abort();
        return;
    }
    uint32_t leaves = 0;
    if (!nrad::format::validateTree(a.grid.dims, a.tree, leaves)) std::abort();  // loaded: must be a valid tree
    const size_t n = 16 * 16;
    std::vector<float> p(3 * n), nrm(3 * n, 0.0f), dir(3 * n, 0.0f), rgb(3 * n);
    for (size_t i = 0; i < n; ++i) {
        p[3 * i] = (float(i % 16) + 0.5f) / 16.0f;
        p[3 * i + 1] = (float(i / 16) + 0.37f) / 16.0f;
        p[3 * i + 2] = float(data[i % size]) / 255.0f;
        nrm[3 * i + 2] = dir[3 * i + 2] = 1.0f;
    }
    nradEvaluateBatch(asset, n, p.data(), nrm.data(), dir.data(), rgb.data(), nullptr);
    for (float v : rgb)
        if (!std::isfinite(v) || v < 0.0f) std::abort();
    nradReleaseAsset(asset);
}

bool finite(const float* v, size_t n) {
    for (size_t i = 0; i < n; ++i)
        if (!std::isfinite(v[i]) || v[i] < 0.0f) return false;
    return true;
}

// What an accepted asset must survive beyond the plain batches: every kernel, huge finite inputs, G-buffers of
// fp16 attributes (shaded, with the input's bytes as material terms), and packing for the GPU.
void exercise(NradAsset asset, const NradAssetInfo& info, const uint8_t* data, size_t size) {
    const size_t n = 48;
    std::vector<float> p(3 * n), nrm(3 * n), dir(3 * n), rgb(3 * n);
    for (size_t i = 0; i < 3 * n; ++i) {
        const int k = int(i % 3);
        p[i] = info.gridLower[k] + float(data[(i * 3) % size]) / 255.0f * (info.gridUpper[k] - info.gridLower[k]);
        const float magnitude = std::pow(10.0f, float(data[(i * 17) % size] % 39));  // up to 1e38
        nrm[i] = (float(int(data[(i * 7) % size]) - 128) / 128.0f) * magnitude;
        dir[i] = float(int(data[(i * 13) % size]) - 128) / 128.0f;
    }
    for (NradKernel k : {NRAD_KERNEL_SCALAR, NRAD_KERNEL_AVX2, NRAD_KERNEL_AVX512, NRAD_KERNEL_NEON}) {
        if (nradSelectKernel(k) != NRAD_OK) continue;
        nradEvaluateBatch(asset, n, p.data(), nrm.data(), dir.data(), rgb.data(), nullptr);
        if (!finite(rgb.data(), rgb.size())) std::abort();
    }
    nradSelectKernel(NRAD_KERNEL_AUTO);

    // A G-buffer of 20-byte texels read from the input: position fp32 (inside the grid), normal and direction
    // fp16 as the bytes say (zero, huge, infinite or NaN included), shaded with surfaces from the bytes.
    struct Texel {
        float position[3];
        uint16_t normal[3], direction[3];
    };
    std::vector<Texel> texels(n);
    std::vector<NradSurface> surfaces(n);
    for (size_t i = 0; i < n; ++i) {
        for (int k = 0; k < 3; ++k) {
            texels[i].position[k] = p[3 * i + size_t(k)];
            texels[i].normal[k] = uint16_t(data[(i * 6 + size_t(k)) % size] | data[(i * 6 + 3 + size_t(k)) % size] << 8);
            texels[i].direction[k] = uint16_t(data[(i * 5 + size_t(k)) % size] | data[(i * 2 + size_t(k)) % size] << 8);
        }
        float m[9];
        for (int j = 0; j < 9; ++j) m[j] = float(data[(i * 9 + size_t(j)) % size]) / 64.0f;
        surfaces[i] = {{m[0], m[1], m[2]}, m[3], m[4], m[5], {m[6], m[7], m[8]}};
    }
    std::vector<float> out(4 * n);
    NradGBuffer g;
    std::memset(&g, 0, sizeof g);
    g.structSize = sizeof g;
    g.flags = data[0] & 1 ? NRAD_GBUFFER_EYE : 0;
    g.count = n;
    g.position = {texels.data()->position, sizeof(Texel), NRAD_FORMAT_F32};
    g.normal = {texels.data()->normal, sizeof(Texel), NRAD_FORMAT_F16};
    g.direction = {texels.data()->direction, sizeof(Texel), NRAD_FORMAT_F16};
    for (int k = 0; k < 3; ++k) g.eye[k] = info.gridUpper[k] + 1.0f;
    g.surfaces = surfaces.data();
    g.output = out.data();
    g.outputChannels = 4;
    if (nradShadeGBuffer(asset, &g, nullptr, 0) != NRAD_OK || !finite(out.data(), out.size())) std::abort();
    // Unshaded into tightly packed RGBA fp16 (the vector kernels write these pixels themselves), texels and
    // pixels ending their allocations, so that a read or write past the last one is the sanitizers' to see.
    std::vector<uint16_t> halves(4 * n);
    g.surfaces = nullptr;
    g.output = halves.data();
    g.outputFormat = NRAD_FORMAT_F16;
    if (nradShadeGBuffer(asset, &g, nullptr, 0) != NRAD_OK) std::abort();
    for (size_t i = 0; i < halves.size(); ++i)
        if ((halves[i] & 0x7C00) == 0x7C00 || (halves[i] & 0x8000 && halves[i] != 0x8000)) std::abort();  // Inf, NaN, < 0

    size_t bytes = 0;
    if (nradGetGpuBufferSize(asset, &bytes) == NRAD_OK) {
        std::vector<uint32_t> words(bytes / 4);
        if (nradPackGpuBuffer(asset, words.data(), bytes) != NRAD_OK || words[0] != 0x5047524Eu || words[36] != words.size())
            std::abort();
    }
}

}  // namespace

#ifdef NRAD_FUZZ_CUSTOM_MUTATOR
extern "C" size_t LLVMFuzzerMutate(uint8_t* data, size_t size, size_t maxSize);

// libFuzzer's mutation, then (three times in four) every CRC recomputed: the mutation reaches the checks past
// the CRCs; the fourth keeps exercising the CRC checks themselves.
extern "C" size_t LLVMFuzzerCustomMutator(uint8_t* data, size_t size, size_t maxSize, unsigned int seed) {
    const size_t n = LLVMFuzzerMutate(data, size, maxSize);
    if (seed % 4 != 0) nrad::fuzz::fixCrcs(data, n);
    return n;
}
#endif

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
    fuzzTree(data, size);
    for (uint32_t flags : {uint32_t(NRAD_LOAD_COPY), uint32_t(NRAD_LOAD_BORROW)}) {
        NradAsset asset = nullptr;
        char message[64];
        NradStatus st = nradLoadFromMemory(data, size, flags, &asset, message, sizeof message);
        if (st != NRAD_OK) {
            if (asset) std::abort();  // a failed load must not hand out a handle
            continue;
        }
        NradAssetInfo info;
        if (nradGetAssetInfo(asset, &info) != NRAD_OK) std::abort();
        const char* json;
        size_t length;
        nradGetMetadata(asset, &json, &length);
        // Points spread over and around the grid, directions from the input's bytes.
        const size_t n = 37;
        std::vector<float> p(3 * n), nrm(3 * n), dir(3 * n), rgb(3 * n);
        std::vector<uint8_t> pf(n);
        for (size_t i = 0; i < 3 * n; ++i) {
            int k = int(i % 3);
            float t = float(data[i % size]) / 255.0f * 1.4f - 0.2f;
            p[i] = info.gridLower[k] + t * (info.gridUpper[k] - info.gridLower[k]);
            nrm[i] = float(int(data[(i * 7) % size]) - 128) / 128.0f;
            dir[i] = float(int(data[(i * 13) % size]) - 128) / 128.0f;
        }
        if (info.volumeNetworks > 0) {  // the volume's networks: the same safety
            if (nradEvaluateVolumeBatch(asset, n, p.data(), nrm.data(), rgb.data(), pf.data()) != NRAD_OK) std::abort();
            for (float v : rgb)
                if (!std::isfinite(v) || v < 0.0f) std::abort();
        } else if (nradEvaluateVolumeBatch(asset, n, p.data(), nrm.data(), rgb.data(), pf.data()) != NRAD_ERROR_INVALID_ARGUMENT) {
            std::abort();
        }
        if (info.glossyNetworks > 0) {  // and its glossy response
            if (nradEvaluateVolumeGlossyBatch(asset, n, p.data(), nrm.data(), dir.data(), rgb.data(), pf.data()) != NRAD_OK) std::abort();
            for (float v : rgb)
                if (!std::isfinite(v) || v < 0.0f) std::abort();
        } else if (nradEvaluateVolumeGlossyBatch(asset, n, p.data(), nrm.data(), dir.data(), rgb.data(), pf.data()) !=
                   NRAD_ERROR_INVALID_ARGUMENT) {
            std::abort();
        }
        nradEvaluateBatch(asset, n, p.data(), nrm.data(), dir.data(), rgb.data(), pf.data());
        for (float v : rgb)
            if (!std::isfinite(v) || v < 0.0f) std::abort();
        float one[3];
        uint32_t flag;
        nradEvaluate(asset, p.data(), nrm.data(), dir.data(), one, &flag);
        if (std::memcmp(one, rgb.data(), sizeof one) != 0) std::abort();  // single and batch agree
        // A coherent batch in SoA layout: 64 points in one voxel (so whole vectors take the SIMD kernels'
        // locate-and-evaluate path), the voxel and the directions from the input's bytes.
        const size_t m = 64;
        std::vector<float> soa[12];
        for (auto& v : soa) v.resize(m);
        std::vector<uint8_t> sf(m);
        for (size_t i = 0; i < m; ++i)
            for (int k = 0; k < 3; ++k) {
                float extent = (info.gridUpper[k] - info.gridLower[k]) / float(info.gridDims[k]);
                uint32_t cell = uint32_t(data[size_t(k) % size]) % info.gridDims[k];
                soa[k][i] = info.gridLower[k] + extent * (float(cell) + 0.25f + 0.5f * float(i) / float(m));
                soa[3 + k][i] = float(int(data[(i * 5 + size_t(k)) % size]) - 128) / 128.0f;
                soa[6 + k][i] = float(int(data[(i * 11 + size_t(k)) % size]) - 128) / 128.0f;
            }
        NradBatchSoA b{soa[0].data(), soa[1].data(), soa[2].data(), soa[3].data(), soa[4].data(), soa[5].data(), soa[6].data(),
                       soa[7].data(), soa[8].data(), soa[9].data(), soa[10].data(), soa[11].data(), sf.data()};
        nradEvaluateBatchSoA(asset, m, &b);
        for (int c = 9; c < 12; ++c)
            for (float v : soa[c])
                if (!std::isfinite(v) || v < 0.0f) std::abort();
        if (flags == NRAD_LOAD_COPY) exercise(asset, info, data, size);
        nradReleaseAsset(asset);
    }
    return 0;
}
