// Atomic file output: write to a temporary file beside the target, then rename, so a reader never sees a
// partial file and a failed or interrupted write leaves nothing behind.
#pragma once

#include <cstdint>
#include <functional>
#include <stdexcept>
#include <string>
#include <vector>

namespace nrad {

class IoError : public std::runtime_error {
public:
    using std::runtime_error::runtime_error;
};

// Calls write(temporaryPath), then renames the temporary file to `path`. On any exception the temporary
// file is removed and an IoError naming `path` is thrown.
void writeFileAtomically(const std::string& path, const std::function<void(const std::string&)>& write);
void writeBytesAtomically(const std::string& path, const std::vector<uint8_t>& bytes);
void writeTextAtomically(const std::string& path, const std::string& text);
// Reads a whole file; throws IoError naming the file.
std::vector<uint8_t> readFileBytes(const std::string& path);

}  // namespace nrad
