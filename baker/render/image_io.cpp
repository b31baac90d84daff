// OpenEXR and PNG output through temporary files.
#include "baker/render/image_io.h"

#include <algorithm>
#include <cmath>
#include <filesystem>

#include <OpenEXR/ImfChannelList.h>
#include <OpenEXR/ImfFrameBuffer.h>
#include <OpenEXR/ImfHeader.h>
#include <OpenEXR/ImfInputFile.h>
#include <OpenEXR/ImfOutputFile.h>
#include <stb_image_write.h>

#include "baker/scene/texture.h"
#include "baker/util/atomic_file.h"
#include "baker/util/paths.h"

namespace nrad {

namespace fs = std::filesystem;

namespace {


}  // namespace

glm::dvec3 Image::mean() const {
    glm::dvec3 sum(0.0);
    for (const glm::vec3& p : pixels) sum += glm::dvec3(p);
    return pixels.empty() ? sum : sum / double(pixels.size());
}

void writeExr(const std::string& path, const Image& image) {
    writeFileAtomically(path, [&](const std::string& tmp) {
        Imf::Header header(image.width, image.height);
        header.channels().insert("R", Imf::Channel(Imf::FLOAT));
        header.channels().insert("G", Imf::Channel(Imf::FLOAT));
        header.channels().insert("B", Imf::Channel(Imf::FLOAT));
        Imf::OutputFile file(tmp.c_str(), header);
        Imf::FrameBuffer fb;
        char* base = reinterpret_cast<char*>(const_cast<glm::vec3*>(image.pixels.data()));
        size_t xs = sizeof(glm::vec3), ys = sizeof(glm::vec3) * size_t(image.width);
        fb.insert("R", Imf::Slice(Imf::FLOAT, base + 0, xs, ys));
        fb.insert("G", Imf::Slice(Imf::FLOAT, base + 4, xs, ys));
        fb.insert("B", Imf::Slice(Imf::FLOAT, base + 8, xs, ys));
        file.setFrameBuffer(fb);
        file.writePixels(image.height);
    });
}

Image readExr(const std::string& path) {
    try {
        Imf::InputFile file(path.c_str());
        Imath::Box2i dw = file.header().dataWindow();
        int w = dw.max.x - dw.min.x + 1, h = dw.max.y - dw.min.y + 1;
        Image image(w, h);
        Imf::FrameBuffer fb;
        char* base = reinterpret_cast<char*>(image.pixels.data()) -
                     (ptrdiff_t(dw.min.x) + ptrdiff_t(dw.min.y) * w) * ptrdiff_t(sizeof(glm::vec3));
        size_t xs = sizeof(glm::vec3), ys = sizeof(glm::vec3) * size_t(w);
        fb.insert("R", Imf::Slice(Imf::FLOAT, base + 0, xs, ys));
        fb.insert("G", Imf::Slice(Imf::FLOAT, base + 4, xs, ys));
        fb.insert("B", Imf::Slice(Imf::FLOAT, base + 8, xs, ys));
        file.setFrameBuffer(fb);
        file.readPixels(dw.min.y, dw.max.y);
        return image;
    } catch (const std::exception& e) {
        throw IoError(path + ": cannot read EXR: " + e.what());
    }
}

void writePng(const std::string& path, const Image& image, float exposure) {
    std::vector<unsigned char> rgb(size_t(image.width) * size_t(image.height) * 3);
    float scale = std::exp2(exposure);
    for (size_t i = 0; i < image.pixels.size(); ++i)
        for (int c = 0; c < 3; ++c) {
            float v = image.pixels[i][c] * scale;
            v = std::isfinite(v) ? std::clamp(v, 0.0f, 1.0f) : 0.0f;
            rgb[3 * i + size_t(c)] = static_cast<unsigned char>(std::lround(linearToSrgb(v) * 255.0f));
        }
    // Encoded in memory, written by writeBytesAtomically: a failed write then names the OS's reason.
    std::vector<uint8_t> png;
    auto append = [](void* context, void* data, int size) {
        auto* out = static_cast<std::vector<uint8_t>*>(context);
        out->insert(out->end(), static_cast<uint8_t*>(data), static_cast<uint8_t*>(data) + size);
    };
    if (!stbi_write_png_to_func(append, &png, image.width, image.height, 3, rgb.data(), image.width * 3))
        throw IoError(path + ": cannot encode PNG");
    writeBytesAtomically(path, png);
}

bool isSupportedImagePath(const std::string& path) {
    std::string ext = lowerExtension(path);
    return ext == ".exr" || ext == ".png";
}

void writeImage(const std::string& path, const Image& image, float exposure) {
    std::string ext = lowerExtension(path);
    if (ext == ".exr")
        writeExr(path, image);
    else if (ext == ".png")
        writePng(path, image, exposure);
    else
        throw IoError(path + ": unsupported image type '" + ext + "' (use .exr or .png)");
}

}  // namespace nrad
