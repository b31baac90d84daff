// NRAD_CHECK(condition): an invariant of the code, never of its input (bad input gets an error code or a
// message). Where it fails, the process stops with the condition, file and line on stderr, in every build:
// a bug that passed silently would otherwise write a wrong asset or read past an array.
#pragma once

#include <cstdio>
#include <cstdlib>

namespace nrad::detail {

[[noreturn]] inline void checkFailed(const char* condition, const char* file, int line) {
    std::fprintf(stderr, "nrad: internal check failed: %s (%s:%d)\n", condition, file, line);
    std::fflush(stderr);
    std::abort();
}

}  // namespace nrad::detail

#define NRAD_CHECK(condition) ((condition) ? (void)0 : ::nrad::detail::checkFailed(#condition, __FILE__, __LINE__))
