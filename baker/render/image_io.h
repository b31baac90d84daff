// Image: a linear RGB float image, and its output as OpenEXR (linear float) or PNG (tonemapped sRGB).
// Files are written atomically: to a temporary file beside the target, then renamed.
#pragma once

#include <stdexcept>
#include <string>
#include <vector>

#include <glm/glm.hpp>

#include "baker/util/atomic_file.h"

namespace nrad {

struct Image {
    int width = 0;
    int height = 0;
    std::vector<glm::vec3> pixels;  // row-major, top row first

    Image() = default;
    Image(int w, int h) : width(w), height(h), pixels(size_t(w) * size_t(h), glm::vec3(0.0f)) {}
    glm::vec3& at(int x, int y) { return pixels[size_t(y) * size_t(width) + size_t(x)]; }
    const glm::vec3& at(int x, int y) const { return pixels[size_t(y) * size_t(width) + size_t(x)]; }
    glm::dvec3 mean() const;
};


// Writes linear float RGB. Throws IoError.
void writeExr(const std::string& path, const Image& image);
// Reads an RGB(A) OpenEXR file (for tests and tools). Throws IoError.
Image readExr(const std::string& path);
// Writes 8-bit sRGB: value x 2^exposure, clamped to [0, 1], sRGB-encoded. Throws IoError.
void writePng(const std::string& path, const Image& image, float exposure = 0.0f);
// Picks EXR or PNG by the extension (.exr / .png, case-insensitive). Throws IoError for anything else.
void writeImage(const std::string& path, const Image& image, float exposure = 0.0f);
// True if the path ends in a supported image extension.
bool isSupportedImagePath(const std::string& path);

}  // namespace nrad
