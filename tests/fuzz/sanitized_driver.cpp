// Deterministic loader checks under AddressSanitizer and UBSan (no libFuzzer needed): for every corpus
// file, every truncated prefix, every single-byte change (three values per byte), and 20,000 seeded random
// multi-byte mutations go through the fuzz target. Usage: sanitized_driver FILE...
#include <cstdint>
#include <cstdio>
#include <fstream>
#include <iterator>
#include <random>
#include <vector>

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size);

int main(int argc, char** argv) {
    size_t inputs = 0;
    for (int f = 1; f < argc; ++f) {
        std::ifstream in(argv[f], std::ios::binary);
        std::vector<uint8_t> bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
        if (bytes.empty()) {
            std::fprintf(stderr, "%s: empty or unreadable\n", argv[f]);
            return 2;
        }
        for (size_t n = 0; n <= bytes.size(); ++n, ++inputs) {
            std::vector<uint8_t> prefix(bytes.begin(), bytes.begin() + long(n));  // exact size: ASan sees overreads
            LLVMFuzzerTestOneInput(prefix.data(), prefix.size());
        }
        for (size_t i = 0; i < bytes.size(); ++i)
            for (uint8_t x : {uint8_t(0x01), uint8_t(0x80), uint8_t(0xFF)}) {
                std::vector<uint8_t> b = bytes;
                b[i] ^= x;
                LLVMFuzzerTestOneInput(b.data(), b.size());
                ++inputs;
            }
        std::mt19937 rng(1234);
        for (int m = 0; m < 20000; ++m, ++inputs) {
            std::vector<uint8_t> b = bytes;
            int changes = 1 + int(rng() % 8);
            for (int c = 0; c < changes; ++c) b[rng() % b.size()] = uint8_t(rng());
            LLVMFuzzerTestOneInput(b.data(), b.size());
        }
    }
    std::printf("sanitized driver: %zu inputs, no crash and no sanitizer report\n", inputs);
    return 0;
}
