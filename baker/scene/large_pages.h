// An allocator for large read-mostly tables (texture images): allocations of 2 MiB or more are aligned to 2 MiB
// and, on Linux, advised to the kernel for transparent huge pages. Lookups into a 2048 x 2048 map land on pages
// dozens of texels apart, so with 4 KiB pages they spread over thousands of pages; with 2 MiB pages a 16 MB map
// is 8 (measured: about +1 point of the tracer against raw Embree on LightsPunctualLamp, docs/performance.md).
// Elsewhere (no madvise, or the kernel declines) it is a plain aligned allocation.
#pragma once

#include <cstddef>
#include <cstdlib>
#include <new>

namespace nrad {

namespace detail {
void* allocateLarge(std::size_t bytes);
void freeLarge(void* p) noexcept;
}  // namespace detail

template <class T>
struct LargePageAllocator {
    using value_type = T;
    LargePageAllocator() = default;
    template <class U>
    LargePageAllocator(const LargePageAllocator<U>&) noexcept {}
    T* allocate(std::size_t n) {
        if (n > std::size_t(-1) / sizeof(T)) throw std::bad_array_new_length();
        return static_cast<T*>(detail::allocateLarge(n * sizeof(T)));
    }
    void deallocate(T* p, std::size_t) noexcept { detail::freeLarge(p); }
    template <class U>
    bool operator==(const LargePageAllocator<U>&) const noexcept { return true; }
    template <class U>
    bool operator!=(const LargePageAllocator<U>&) const noexcept { return false; }
};

}  // namespace nrad
