// Environment description, lookup and loading (.exr through OpenEXR, .hdr through stb_image).
#include "baker/scene/environment.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>

#include <OpenEXR/ImfChannelList.h>
#include <OpenEXR/ImfFrameBuffer.h>
#include <OpenEXR/ImfHeader.h>
#include <OpenEXR/ImfInputFile.h>
#include <stb_image.h>

#include "baker/scene/gltf_loader.h"
#include "baker/util/maths.h"
#include "baker/util/paths.h"

namespace nrad {

namespace {


// Rotation about +Y by `degrees` (counter-clockwise seen from above) applied to v.
glm::vec3 rotateY(const glm::vec3& v, float degrees) {
    if (degrees == 0.0f) return v;
    float a = degrees * (kPi / 180.0f), c = std::cos(a), s = std::sin(a);
    return {c * v.x + s * v.z, v.y, -s * v.x + c * v.z};
}

void readExrMap(const std::string& path, Environment& env) {
    try {
        Imf::InputFile file(path.c_str());
        Imath::Box2i dw = file.header().dataWindow();
        int w = dw.max.x - dw.min.x + 1, h = dw.max.y - dw.min.y + 1;
        if (w <= 0 || h <= 0) throw SceneError(path + ": empty image");
        std::vector<float> rgb(size_t(w) * size_t(h) * 3, 0.0f);
        Imf::FrameBuffer fb;
        char* base = reinterpret_cast<char*>(rgb.data()) -
                     (ptrdiff_t(dw.min.x) + ptrdiff_t(dw.min.y) * ptrdiff_t(w)) * ptrdiff_t(3 * sizeof(float));
        size_t xs = 3 * sizeof(float), ys = xs * size_t(w);
        // A missing channel reads as its fill value: a luminance-only map is grey through Y -> R = G = B below.
        const bool luminanceOnly = !file.header().channels().findChannel("R") && file.header().channels().findChannel("Y");
        if (luminanceOnly) {
            fb.insert("Y", Imf::Slice(Imf::FLOAT, base, xs, ys, 1, 1, 0.0));
        } else {
            fb.insert("R", Imf::Slice(Imf::FLOAT, base + 0, xs, ys, 1, 1, 0.0));
            fb.insert("G", Imf::Slice(Imf::FLOAT, base + 4, xs, ys, 1, 1, 0.0));
            fb.insert("B", Imf::Slice(Imf::FLOAT, base + 8, xs, ys, 1, 1, 0.0));
        }
        file.setFrameBuffer(fb);
        file.readPixels(dw.min.y, dw.max.y);
        env.width = w;
        env.height = h;
        env.texels.resize(size_t(w) * size_t(h));
        for (size_t i = 0; i < env.texels.size(); ++i)
            env.texels[i] = luminanceOnly ? glm::vec3(rgb[3 * i]) : glm::vec3(rgb[3 * i], rgb[3 * i + 1], rgb[3 * i + 2]);
    } catch (const SceneError&) {
        throw;
    } catch (const std::exception& e) {
        throw SceneError(path + ": not a readable OpenEXR image (" + e.what() + ")");
    }
}

void readHdrMap(const std::string& path, Environment& env) {
    int w = 0, h = 0, channels = 0;
    float* data = stbi_loadf(path.c_str(), &w, &h, &channels, 3);
    if (!data) {
        const char* why = stbi_failure_reason();
        throw SceneError(path + ": not a readable Radiance .hdr image (" + (why ? why : "unknown reason") + ")");
    }
    env.width = w;
    env.height = h;
    env.texels.resize(size_t(w) * size_t(h));
    for (size_t i = 0; i < env.texels.size(); ++i) env.texels[i] = glm::vec3(data[3 * i], data[3 * i + 1], data[3 * i + 2]);
    stbi_image_free(data);
}

}  // namespace

bool Environment::active() const {
    if (!(intensity > 0.0f)) return false;
    switch (kind) {
        case Kind::None: return false;
        case Kind::Constant: return color.x > 0.0f || color.y > 0.0f || color.z > 0.0f;
        case Kind::Map: return width > 0 && height > 0;
    }
    return false;
}

glm::vec2 Environment::mapCoordinates(const glm::vec3& towards) const {
    glm::vec3 d = rotateY(towards, -rotationDegrees);
    float theta = std::acos(std::clamp(d.y, -1.0f, 1.0f));
    float phi = std::atan2(d.x, -d.z);
    float u = 0.5f + phi * (0.5f / kPi);
    return {u - std::floor(u), theta / kPi};
}

glm::vec3 Environment::direction(glm::vec2 uv) const {
    float phi = (uv.x - 0.5f) * (2.0f * kPi), theta = uv.y * kPi;
    float st = std::sin(theta);
    glm::vec3 d(st * std::sin(phi), std::cos(theta), -st * std::cos(phi));
    return rotateY(d, rotationDegrees);
}

glm::vec3 Environment::radiance(const glm::vec3& towards) const {
    switch (kind) {
        case Kind::None: return glm::vec3(0.0f);
        case Kind::Constant: return intensity * color;
        case Kind::Map: {
            if (width <= 0 || height <= 0) return glm::vec3(0.0f);
            glm::vec2 uv = mapCoordinates(towards);
            int x = std::min(width - 1, int(uv.x * float(width)));
            int y = std::min(height - 1, int(uv.y * float(height)));
            return intensity * texels[size_t(y) * size_t(width) + size_t(x)];
        }
    }
    return glm::vec3(0.0f);
}

glm::vec3 Environment::meanRadiance() const {
    if (kind == Kind::Constant) return intensity * color;
    if (kind != Kind::Map || width <= 0 || height <= 0) return glm::vec3(0.0f);
    glm::dvec3 sum(0.0);
    for (int y = 0; y < height; ++y) {
        // Solid angle of a texel of row y: (2 pi / W) (cos theta0 - cos theta1), over 4 pi.
        double c0 = std::cos(double(kPi) * y / height), c1 = std::cos(double(kPi) * (y + 1) / height);
        double w = (c0 - c1) / (2.0 * width);
        for (int x = 0; x < width; ++x) sum += w * glm::dvec3(texels[size_t(y) * size_t(width) + size_t(x)]);
    }
    return intensity * glm::vec3(sum);
}

std::string Environment::describe() const {
    char b[160];
    switch (kind) {
        case Kind::None: return "none";
        case Kind::Constant:
            std::snprintf(b, sizeof b, "constant radiance %g,%g,%g", double(color.x * intensity), double(color.y * intensity),
                          double(color.z * intensity));
            return (isDefault ? "default sky, " : "") + std::string(b);
        case Kind::Map:
            std::snprintf(b, sizeof b, " (%dx%d), intensity %g, rotation %g degrees", width, height, double(intensity),
                          double(rotationDegrees));
            return "map " + source + b;
    }
    return "none";
}

Environment defaultSky() {
    Environment e;
    e.kind = Environment::Kind::Constant;
    e.color = glm::vec3(1.0f);
    e.source = "default sky";
    e.isDefault = true;
    return e;
}

Environment parseEnvironment(const std::string& spec, float intensity, float rotationDegrees) {
    if (!std::isfinite(intensity) || intensity < 0.0f)
        throw EnvironmentSpecError("--environment-intensity " + std::to_string(intensity) + ": expected a finite value >= 0");
    if (!std::isfinite(rotationDegrees))
        throw EnvironmentSpecError("--environment-rotation: expected a finite angle in degrees");
    Environment e;
    e.intensity = intensity;
    e.rotationDegrees = rotationDegrees;
    e.source = spec;
    if (spec == "none") return e;
    // r,g,b
    float r, g, b;
    char rest;
    if (std::sscanf(spec.c_str(), "%f,%f,%f%c", &r, &g, &b, &rest) == 3) {
        if (!std::isfinite(r) || !std::isfinite(g) || !std::isfinite(b) || r < 0.0f || g < 0.0f || b < 0.0f)
            throw EnvironmentSpecError("--environment " + spec + ": expected three finite values >= 0 (r,g,b) or an .exr/.hdr file");
        e.kind = Environment::Kind::Constant;
        e.color = {r, g, b};
        return e;
    }
    std::error_code ec;
    if (!std::filesystem::is_regular_file(spec, ec))
        throw SceneError(spec + ": no such environment map (expected none, r,g,b, or an .exr or .hdr file)");
    std::string ext = lowerExtension(spec);
    if (ext == ".exr")
        readExrMap(spec, e);
    else if (ext == ".hdr")
        readHdrMap(spec, e);
    else
        throw SceneError(spec + ": unsupported environment map type '" + ext + "' (use .exr or .hdr)");
    e.kind = Environment::Kind::Map;
    for (size_t i = 0; i < e.texels.size(); ++i) {
        const glm::vec3& t = e.texels[i];
        for (int c = 0; c < 3; ++c)
            if (!std::isfinite(t[c]) || t[c] < 0.0f) {
                char b2[128];
                std::snprintf(b2, sizeof b2, ": texel (%zu, %zu) is %g: radiance must be finite and >= 0", i % size_t(e.width),
                              i / size_t(e.width), double(t[c]));
                throw SceneError(spec + b2);
            }
    }
    return e;
}

}  // namespace nrad
