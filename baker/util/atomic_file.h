// Atomic file output: write to a temporary file beside the target, then rename, so a reader never sees a
// partial file and a failed or interrupted write leaves nothing behind. The temporary's name is the
// target's with `.nrad-partial-PID-N` appended: recognisable, and removed by the next write of the same
// target once process PID is gone (a write killed midway cannot clean up after itself).
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

// The same for a folder: write(temporaryFolder) fills a new folder beside `path`, which then replaces `path`
// (an earlier folder of that name, such as the last report, is removed only once the new one is in place).
void writeFolderAtomically(const std::string& path, const std::function<void(const std::string&)>& write);

// Reads a whole file; throws IoError naming the file.
std::vector<uint8_t> readFileBytes(const std::string& path);

// Whether an output can be written where the user asked, checked before any work: commands call it first
// so that a typo in -o costs a second, not a bake. Creates and removes the temporary the write would use.
enum class OutputProblem {
    kNone,
    kIsFolder,  // a file output names an existing folder (a usage error)
    kIsFile,  // a folder output names an existing file (a usage error)
    kCannotCreate,  // the folder does not exist, is not writable, ... (`message` has the OS's reason)
};
struct OutputCheck {
    OutputProblem problem = OutputProblem::kNone;
    std::string message;  // "PATH: why", empty when kNone
};
OutputCheck checkOutputFile(const std::string& path);
OutputCheck checkOutputFolder(const std::string& path);

}  // namespace nrad
