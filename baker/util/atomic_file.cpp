// Temporary-file-and-rename output.
#include "baker/util/atomic_file.h"

#include <atomic>
#include <cerrno>
#include <csignal>
#include <cstring>
#include <filesystem>
#include <fstream>

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

namespace nrad {

namespace fs = std::filesystem;

namespace {

constexpr const char* kPartial = ".nrad-partial-";

// `path` + ".nrad-partial-PID-N": unique within the process (N counts) and across processes (PID).
std::string temporaryName(const std::string& path) {
    static std::atomic<uint64_t> counter{0};
    return path + kPartial + std::to_string(::getpid()) + "-" + std::to_string(counter++);
}

// Removes what writes of `path` left behind when their process died mid-write: `path.nrad-partial-PID-N`
// whose PID is not running (and `path.tmp-N`, the name earlier versions used). A live process's temporaries
// are left alone: it may be writing right now.
void removeStaleTemporaries(const std::string& path) {
    const fs::path target(path);
    const fs::path dir = target.parent_path().empty() ? fs::path(".") : target.parent_path();
    const std::string partial = target.filename().string() + kPartial, old = target.filename().string() + ".tmp-";
    std::error_code ec;
    for (fs::directory_iterator it(dir, ec), end; !ec && it != end; it.increment(ec)) {
        const std::string name = it->path().filename().string();
        bool stale = false;
        if (name.rfind(partial, 0) == 0) {
            const std::string rest = name.substr(partial.size());
            const long pid = std::strtol(rest.c_str(), nullptr, 10);
            stale = pid > 0 && ::kill(pid_t(pid), 0) != 0 && errno == ESRCH;
        } else if (name.rfind(old, 0) == 0) {
            stale = name.size() > old.size() && name.find_first_not_of("0123456789", old.size()) == std::string::npos;
        }
        if (stale) {
            std::error_code ignored;
            fs::remove_all(it->path(), ignored);
        }
    }
}

std::string osError(int error) { return std::strerror(error); }

}  // namespace

void writeFileAtomically(const std::string& path, const std::function<void(const std::string&)>& write) {
    removeStaleTemporaries(path);
    const std::string tmp = temporaryName(path);
    try {
        write(tmp);
        std::error_code ec;
        fs::rename(tmp, path, ec);
        if (ec) throw IoError(path + ": cannot write file: " + ec.message());
    } catch (const IoError&) {
        std::error_code ignored;
        fs::remove(tmp, ignored);
        throw;
    } catch (const std::exception& e) {
        std::error_code ignored;
        fs::remove(tmp, ignored);
        throw IoError(path + ": cannot write file: " + e.what());
    }
}

void writeBytesAtomically(const std::string& path, const std::vector<uint8_t>& bytes) {
    // POSIX calls rather than a stream: a full disk must be reported as the OS says it ("No space left on
    // device"), not as a stream's failbit.
    writeFileAtomically(path, [&](const std::string& tmp) {
        const int fd = ::open(tmp.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0666);
        if (fd < 0) throw IoError(path + ": cannot create file: " + osError(errno));
        const uint8_t* p = bytes.data();
        size_t left = bytes.size();
        while (left > 0) {
            const ssize_t n = ::write(fd, p, left);
            if (n < 0 && errno == EINTR) continue;
            if (n <= 0) {
                const int error = n < 0 ? errno : EIO;
                ::close(fd);
                throw IoError(path + ": write failed: " + osError(error));
            }
            p += n;
            left -= size_t(n);
        }
        if (::close(fd) != 0) throw IoError(path + ": write failed: " + osError(errno));
    });
}

void writeTextAtomically(const std::string& path, const std::string& text) {
    writeBytesAtomically(path, std::vector<uint8_t>(text.begin(), text.end()));
}

void writeFolderAtomically(const std::string& path, const std::function<void(const std::string&)>& write) {
    removeStaleTemporaries(path);
    const std::string tmp = temporaryName(path);
    std::error_code ec;
    if (!fs::create_directories(tmp, ec) || ec) throw IoError(path + ": cannot create the folder: " + ec.message());
    try {
        write(tmp);
        std::string previous;
        if (fs::is_directory(path, ec)) {
            previous = temporaryName(path);
            fs::rename(path, previous, ec);
            if (ec) throw IoError(path + ": cannot replace the folder: " + ec.message());
        }
        fs::rename(tmp, path, ec);
        if (ec) {
            if (!previous.empty()) fs::rename(previous, path, ec);  // put the old one back
            throw IoError(path + ": cannot write the folder: " + ec.message());
        }
        if (!previous.empty()) fs::remove_all(previous, ec);
    } catch (const IoError&) {
        fs::remove_all(tmp, ec);
        throw;
    } catch (const std::exception& e) {
        fs::remove_all(tmp, ec);
        throw IoError(path + ": cannot write the folder: " + e.what());
    }
}

std::vector<uint8_t> readFileBytes(const std::string& path) {
    std::ifstream f(path, std::ios::binary);
    if (!f) throw IoError(path + ": cannot open file");
    return std::vector<uint8_t>((std::istreambuf_iterator<char>(f)), std::istreambuf_iterator<char>());
}

OutputCheck checkOutputFile(const std::string& path) {
    std::error_code ec;
    if (path.empty()) return {OutputProblem::kCannotCreate, "the output path is empty"};
    if (fs::is_directory(path, ec)) return {OutputProblem::kIsFolder, path + ": is a folder; name a file"};
    const std::string probe = temporaryName(path);
    const int fd = ::open(probe.c_str(), O_WRONLY | O_CREAT | O_EXCL | O_CLOEXEC, 0666);
    if (fd < 0) return {OutputProblem::kCannotCreate, path + ": cannot create file: " + osError(errno)};
    ::close(fd);
    ::unlink(probe.c_str());
    return {};
}

OutputCheck checkOutputFolder(const std::string& path) {
    std::error_code ec;
    if (path.empty()) return {OutputProblem::kCannotCreate, "the output path is empty"};
    if (fs::exists(path, ec) && !fs::is_directory(path, ec))
        return {OutputProblem::kIsFile, path + ": is a file; name a folder"};
    const fs::path parent = fs::path(path).parent_path();
    if (!parent.empty()) fs::create_directories(parent, ec);  // as the write would (its error shows just below)
    const std::string probe = temporaryName(path);
    if (::mkdir(probe.c_str(), 0777) != 0) return {OutputProblem::kCannotCreate, path + ": cannot create the folder: " + osError(errno)};
    ::rmdir(probe.c_str());
    return {};
}

}  // namespace nrad
