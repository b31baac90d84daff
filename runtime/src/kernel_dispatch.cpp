// The kernel table and the choice of kernel: CPU checks, the process-wide and per-asset kernel.
#include "kernel_dispatch.h"

#include <atomic>

#if (defined(__x86_64__) || defined(_M_X64)) && defined(__GNUC__)
#include <cpuid.h>
#endif

#include "asset.h"

namespace nrad::rt {
namespace {

bool always() { return true; }

#if defined(__x86_64__) || defined(_M_X64)
bool hasAvx2() {
#if defined(__GNUC__)
    __builtin_cpu_init();
    return __builtin_cpu_supports("avx2") && __builtin_cpu_supports("fma");
#else
    return false;
#endif
}

bool hasAvx512() {
#if defined(__GNUC__)
    __builtin_cpu_init();
    return __builtin_cpu_supports("avx512f");
#else
    return false;
#endif
}

// F16C, which the AVX2 conversions need besides AVX2: CPUID leaf 1, ECX bit 29 (clang's __builtin_cpu_supports
// does not know the name).
bool hasF16c() {
#if defined(__GNUC__)
    static const bool f16c = hasAvx2() && [] {
        unsigned eax = 0, ebx = 0, ecx = 0, edx = 0;
        return __get_cpuid(1, &eax, &ebx, &ecx, &edx) && (ecx & (1u << 29)) != 0;
    }();
    return f16c;
#else
    return false;
#endif
}
#endif

// A row's entries past its id where this build has the kernel, else none (null `supported`: not in this build).
#define NRAD_NOT_IN_THIS_BUILD nullptr, nullptr, nullptr, 0, nullptr, nullptr, nullptr
#if defined(__x86_64__) || defined(_M_X64)
#define NRAD_X86_ONLY(...) __VA_ARGS__
#else
#define NRAD_X86_ONLY(...) NRAD_NOT_IN_THIS_BUILD
#endif
#if defined(__aarch64__)
#define NRAD_AARCH64_ONLY(...) __VA_ARGS__
#else
#define NRAD_AARCH64_ONLY(...) NRAD_NOT_IN_THIS_BUILD
#endif

// Every kernel the API names, fastest first (bestKernel takes the first this CPU supports). Each row:
// {id, supported, evalChunk, evalBlocks, blockWidth, halfToFloat, floatToHalf, halfSupported}.
// clang-format off
constexpr KernelEntry kKernels[] = {
    {NRAD_KERNEL_AVX512, NRAD_X86_ONLY(hasAvx512, evalChunkAvx512, evalBlocksAvx512, kAvx512Width, halfToFloatF16c, floatToHalfF16c, hasF16c)},
    {NRAD_KERNEL_AVX2,   NRAD_X86_ONLY(hasAvx2,   evalChunkAvx2,   evalBlocksAvx2,   kAvx2Width,   halfToFloatF16c, floatToHalfF16c, hasF16c)},
    {NRAD_KERNEL_NEON,   NRAD_AARCH64_ONLY(always, evalChunkNeon,  evalBlocksNeon,   kNeonWidth,   halfToFloatNeon, floatToHalfNeon, nullptr)},
    {NRAD_KERNEL_SCALAR, always,                  evalChunkScalar, nullptr,          0,            halfToFloatScalar, floatToHalfScalar, nullptr},
};
// clang-format on
constexpr const KernelEntry& kScalar = kKernels[sizeof kKernels / sizeof kKernels[0] - 1];
static_assert(kScalar.id == NRAD_KERNEL_SCALAR && kScalar.evalBlocks == nullptr, "the scalar kernel is the last resort");

std::atomic<int> gKernel{NRAD_KERNEL_AUTO};

}  // namespace

const KernelEntry* findKernel(NradKernel k) {
    for (const KernelEntry& e : kKernels)
        if (e.id == k) return &e;
    return nullptr;
}

const KernelEntry& kernelEntry(NradKernel k) {
    const KernelEntry* e = findKernel(k);
    return e && e->supported ? *e : kScalar;
}

bool kernelSupported(NradKernel k) {
    const KernelEntry* e = findKernel(k);
    return e && e->supported && e->supported();
}

NradKernel bestKernel() {
    for (const KernelEntry& e : kKernels)
        if (e.supported && e.supported()) return e.id;
    return NRAD_KERNEL_SCALAR;
}

NradKernel activeKernel() {
    int k = gKernel.load(std::memory_order_relaxed);
    if (k == NRAD_KERNEL_AUTO) {
        k = bestKernel();
        gKernel.store(k, std::memory_order_relaxed);
    }
    return NradKernel(k);
}

void setActiveKernel(NradKernel k) { gKernel.store(k); }

NradKernel kernelOf(const NradAsset_& a) {
    const int k = a.kernel.load(std::memory_order_relaxed);
    return k == NRAD_KERNEL_AUTO ? activeKernel() : NradKernel(k);
}

HalfConverters halfConverters(NradKernel k) {
    const KernelEntry& e = kernelEntry(k);
    if (!e.halfSupported || e.halfSupported()) return {e.halfToFloat, e.floatToHalf};
    return {kScalar.halfToFloat, kScalar.floatToHalf};
}

}  // namespace nrad::rt
