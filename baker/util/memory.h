// What this process can still allocate, so that a command refuses up front (with the figure) what it could
// not finish, rather than end in std::bad_alloc after minutes of work.
#pragma once

#include <cstdint>
#include <string>

namespace nrad {

// Bytes the process could allocate now: the least of the machine's available memory (MemAvailable), the
// container's (cgroup v2 memory.max less memory.current) and the address-space and data limits (ulimit -v,
// -d) less what is mapped. UINT64_MAX where nothing is known.
uint64_t availableMemoryBytes();

// "12.3 GiB"
std::string gibibytes(uint64_t bytes);

}  // namespace nrad
