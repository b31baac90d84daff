// Temporary-file-and-rename output.
#include "baker/util/atomic_file.h"

#include <cstdio>
#include <filesystem>
#include <fstream>
#include <random>

namespace nrad {

namespace fs = std::filesystem;

void writeFileAtomically(const std::string& path, const std::function<void(const std::string&)>& write) {
    std::random_device rd;
    std::string tmp = path + ".tmp-" + std::to_string(rd());
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
    writeFileAtomically(path, [&](const std::string& tmp) {
        std::ofstream f(tmp, std::ios::binary | std::ios::trunc);
        if (!f) throw IoError(path + ": cannot create file");
        f.write(reinterpret_cast<const char*>(bytes.data()), std::streamsize(bytes.size()));
        f.flush();
        if (!f) throw IoError(path + ": write failed");
    });
}

void writeTextAtomically(const std::string& path, const std::string& text) {
    writeBytesAtomically(path, std::vector<uint8_t>(text.begin(), text.end()));
}

std::vector<uint8_t> readFileBytes(const std::string& path) {
    std::ifstream f(path, std::ios::binary);
    if (!f) throw IoError(path + ": cannot open file");
    return std::vector<uint8_t>((std::istreambuf_iterator<char>(f)), std::istreambuf_iterator<char>());
}

}  // namespace nrad
