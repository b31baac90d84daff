// FNV-1a (64-bit) over bytes: the scene and settings hashes that key caches and assets' metadata.
#pragma once

#include <cstddef>
#include <cstdint>

namespace nrad {

inline constexpr uint64_t kFnvOffsetBasis = 0xcbf29ce484222325ull;

// Continues the hash h over `bytes` bytes at `data`.
inline void fnv1a(uint64_t& h, const void* data, size_t bytes) {
    const auto* p = static_cast<const unsigned char*>(data);
    for (size_t i = 0; i < bytes; ++i) {
        h ^= p[i];
        h *= 0x100000001b3ull;
    }
}

}  // namespace nrad
