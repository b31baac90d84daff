// Loading an asset: the format's validating decoder, then the tables evaluation reads (kd-tree boxes and tags,
// the rectilinear table, the dense cell -> network table).
#pragma once

#include <cstddef>
#include <cstdint>
#include <string>

#include <nrad/nrad.h>

namespace nrad::rt {

// nradLoadFromMemory's work, without its exception guard.
NradStatus loadAsset(const void* data, size_t size, uint32_t flags, NradAsset* out, char* message, size_t messageSize);
// `text` into the caller's message buffer (nothing where it is null or empty), truncated and NUL-terminated.
void writeMessage(char* message, size_t size, const std::string& text);

}  // namespace nrad::rt
