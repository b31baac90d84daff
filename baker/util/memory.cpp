// Available memory from /proc, /sys/fs/cgroup and the resource limits.
#include "baker/util/memory.h"

#include <algorithm>
#include <cstdio>
#include <fstream>
#include <limits>
#include <string>

#include <sys/resource.h>
#include <unistd.h>

namespace nrad {

namespace {

constexpr uint64_t kUnknown = std::numeric_limits<uint64_t>::max();

uint64_t meminfoAvailable() {
    std::ifstream f("/proc/meminfo");
    std::string key;
    uint64_t kib = 0;
    std::string unit;
    while (f >> key >> kib >> unit)
        if (key == "MemAvailable:") return kib * 1024;
    return kUnknown;
}

uint64_t readNumber(const char* path) {
    std::ifstream f(path);
    std::string text;
    if (!(f >> text) || text == "max") return kUnknown;
    try {
        return std::stoull(text);
    } catch (...) {
        return kUnknown;
    }
}

uint64_t cgroupAvailable() {
    const uint64_t limit = readNumber("/sys/fs/cgroup/memory.max"), used = readNumber("/sys/fs/cgroup/memory.current");
    if (limit == kUnknown) return kUnknown;
    return used == kUnknown || used >= limit ? (used == kUnknown ? limit : 0) : limit - used;
}

uint64_t mappedBytes() {
    std::ifstream f("/proc/self/statm");
    uint64_t pages = 0;
    return f >> pages ? pages * uint64_t(::sysconf(_SC_PAGESIZE)) : 0;
}

uint64_t limitHeadroom(int resource) {
    rlimit r{};
    if (::getrlimit(resource, &r) != 0 || r.rlim_cur == RLIM_INFINITY) return kUnknown;
    const uint64_t mapped = mappedBytes();
    return uint64_t(r.rlim_cur) > mapped ? uint64_t(r.rlim_cur) - mapped : 0;
}

}  // namespace

uint64_t availableMemoryBytes() {
    return std::min({meminfoAvailable(), cgroupAvailable(), limitHeadroom(RLIMIT_AS), limitHeadroom(RLIMIT_DATA)});
}

std::string gibibytes(uint64_t bytes) {
    char text[32];
    std::snprintf(text, sizeof text, "%.1f GiB", double(bytes) / double(uint64_t(1) << 30));
    return text;
}

}  // namespace nrad
