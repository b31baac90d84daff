// Recomputes an .nrad file's CRCs in place (every section whose range lies inside the buffer, the section
// table's, the header's), so that a fuzzer's mutation of a section's bytes reaches the decoder's checks beyond
// the CRCs instead of stopping at them. Whatever the bytes say, it reads and writes only inside the buffer.
#pragma once

#include <cstddef>
#include <cstdint>
#include <cstring>

#include <nrad/format.h>

namespace nrad::fuzz {

inline uint32_t load32(const uint8_t* p) {
    uint32_t v;
    std::memcpy(&v, p, 4);
    return v;
}
inline uint64_t load64(const uint8_t* p) {
    uint64_t v;
    std::memcpy(&v, p, 8);
    return v;
}
inline void store32(uint8_t* p, uint32_t v) { std::memcpy(p, &v, 4); }

inline void fixCrcs(uint8_t* d, size_t size) {
    if (size < format::kHeaderSize) return;
    const uint64_t count = load32(d + 20), table = load64(d + 32);
    if (count <= format::kMaxSections && table <= size && count * format::kSectionRecordSize <= size - table) {
        for (uint64_t i = 0; i < count; ++i) {
            uint8_t* r = d + table + i * format::kSectionRecordSize;
            const uint64_t offset = load64(r + 8), length = load64(r + 16);
            if (offset <= size && length <= size - offset) store32(r + 24, format::crc32(d + offset, size_t(length)));
        }
        store32(d + 40, format::crc32(d + table, size_t(count * format::kSectionRecordSize)));
    }
    store32(d + 60, format::crc32(d, 60));
}

}  // namespace nrad::fuzz
