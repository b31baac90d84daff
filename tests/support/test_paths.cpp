// Test path helpers.
#include "support/test_paths.h"

#include <atomic>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <mutex>
#include <vector>

#include <sys/wait.h>
#include <unistd.h>

namespace nrad::test {

namespace fs = std::filesystem;

std::string sourcePath(const std::string& relative) { return std::string(NRAD_SOURCE_DIR) + "/" + relative; }
std::string externalScene(const std::string& relative) { return std::string(NRAD_EXTERNAL_SCENES) + "/" + relative; }
std::string nradExecutable() { return NRAD_EXE; }

namespace {
struct Cleanup {
    std::mutex mutex;
    std::vector<fs::path> dirs;
    ~Cleanup() {
        for (const fs::path& d : dirs) {
            std::error_code ec;
            fs::remove_all(d, ec);
        }
    }
};
Cleanup& cleanup() {
    static Cleanup c;
    return c;
}
}  // namespace

std::string temporaryDirectory() {
    static std::atomic<int> counter{0};
    fs::path dir = fs::temp_directory_path() /
                   ("nrad-test-" + std::to_string(getpid()) + "-" + std::to_string(counter++));
    fs::create_directories(dir);
    std::lock_guard<std::mutex> lock(cleanup().mutex);
    cleanup().dirs.push_back(dir);
    return dir.string();
}

CommandResult runCommand(const std::string& command) {
    FILE* pipe = popen((command + " 2>&1").c_str(), "r");
    if (!pipe) return {-1, ""};
    std::string out;
    char buf[4096];
    size_t n;
    while ((n = fread(buf, 1, sizeof buf, pipe)) > 0) out.append(buf, n);
    const int status = pclose(pipe);
    return {WIFEXITED(status) ? WEXITSTATUS(status) : -1, out};
}

std::string fileBytes(const std::string& path) {
    std::ifstream in(path, std::ios::binary);
    return std::string((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
}

}  // namespace nrad::test
