// glTF material features as the spec defines them, through the importer and the path tracer, in scenes
// with closed-form answers: a normal-mapped plane under a directional light shades with the cosine of the
// perturbed normal (generated tangents and given TANGENTs), an alpha-checkerboard occluder passes half the
// light (MASK) and a uniform BLEND occluder 1 - alpha of it, COLOR_0 multiplies the base colour, and
// KHR_texture_transform moves the texture as its matrix says. The glTF files are written here.
#include <cmath>
#include <cstring>
#include <fstream>
#include <string>
#include <vector>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "baker/render/accel.h"
#include "baker/render/image_io.h"
#include "baker/lights/light_sampler.h"
#include "baker/render/path_tracer.h"
#include "baker/render/surface.h"
#include "baker/scene/gltf_loader.h"
#include "baker/scene/texture.h"
#include "baker/util/threads.h"

namespace nrad {
namespace {

constexpr double kPi = 3.14159265358979323846;

// One axis-aligned square [-h, h]^2 at height z, facing +Z (or -Z), UVs u = (x + h) / 2h, v = (h - y) / 2h.
struct Quad {
    float z = 0.0f;
    float half = 1.0f;
    bool faceDown = false;
    int material = 0;
    bool colors = false;
    glm::vec4 color{1.0f};
    bool tangents = false;
    glm::vec4 tangent{1, 0, 0, 1};
};

// A minimal 8-bit PNG of 1 (grey), 2 (grey, alpha), 3 (RGB) or 4 (RGBA) channels: zlib "stored" blocks, no
// compression (so the test needs no image library).
void writePng(const std::string& path, int w, int h, int channels, const std::vector<unsigned char>& pixels) {
    auto crc = [](const std::vector<unsigned char>& d, size_t from) {
        uint32_t c = 0xffffffffu;
        for (size_t i = from; i < d.size(); ++i) {
            c ^= d[i];
            for (int k = 0; k < 8; ++k) c = (c >> 1) ^ (0xedb88320u & (0u - (c & 1u)));
        }
        return c ^ 0xffffffffu;
    };
    auto be32 = [](std::vector<unsigned char>& d, uint32_t v) {
        for (int s = 24; s >= 0; s -= 8) d.push_back((unsigned char)(v >> s));
    };
    std::vector<unsigned char> file = {0x89, 'P', 'N', 'G', '\r', '\n', 0x1a, '\n'};
    auto chunk = [&](const char* type, const std::vector<unsigned char>& data) {
        be32(file, uint32_t(data.size()));
        size_t start = file.size();
        file.insert(file.end(), type, type + 4);
        file.insert(file.end(), data.begin(), data.end());
        be32(file, crc(file, start));
    };
    std::vector<unsigned char> ihdr;
    be32(ihdr, uint32_t(w));
    be32(ihdr, uint32_t(h));
    const unsigned char colourType[5] = {0, 0, 4, 2, 6};  // PNG colour type of each channel count
    ihdr.insert(ihdr.end(), {8, colourType[channels], 0, 0, 0});
    chunk("IHDR", ihdr);
    std::vector<unsigned char> raw;
    for (int y = 0; y < h; ++y) {
        raw.push_back(0);  // filter: none
        raw.insert(raw.end(), pixels.begin() + std::ptrdiff_t(y) * w * channels, pixels.begin() + std::ptrdiff_t(y + 1) * w * channels);
    }
    std::vector<unsigned char> z = {0x78, 0x01};
    for (size_t at = 0; at < raw.size() || at == 0;) {
        size_t n = std::min<size_t>(65535, raw.size() - at);
        bool last = at + n >= raw.size();
        z.push_back(last ? 1 : 0);
        z.push_back((unsigned char)(n & 0xff));
        z.push_back((unsigned char)(n >> 8));
        z.push_back((unsigned char)(~n & 0xff));
        z.push_back((unsigned char)((~n >> 8) & 0xff));
        z.insert(z.end(), raw.begin() + std::ptrdiff_t(at), raw.begin() + std::ptrdiff_t(at + n));
        at += n;
        if (last) break;
    }
    uint32_t a = 1, b = 0;
    for (unsigned char c : raw) {
        a = (a + c) % 65521u;
        b = (b + a) % 65521u;
    }
    be32(z, (b << 16) | a);
    chunk("IDAT", z);
    chunk("IEND", {});
    std::ofstream(path, std::ios::binary).write(reinterpret_cast<const char*>(file.data()), std::streamsize(file.size()));
}

// Writes DIR/NAME.gltf (+ .bin) with the quads, the materials (JSON) and 8-bit RGBA PNG images (given as
// byte rows) referenced by textures 0.. in order.
std::string writeGltf(const std::string& dir, const std::string& name, const std::vector<Quad>& quads,
                      const nlohmann::json& materials, const std::vector<Image>& images = {},
                      const std::vector<std::vector<uint8_t>>& alphas = {}) {
    std::vector<uint8_t> bin;
    auto put = [&](const void* p, size_t n) {
        const auto* b = static_cast<const uint8_t*>(p);
        bin.insert(bin.end(), b, b + n);
        while (bin.size() % 4) bin.push_back(0);
    };
    nlohmann::json views = nlohmann::json::array(), accessors = nlohmann::json::array(), meshes = nlohmann::json::array(),
                   nodes = nlohmann::json::array();
    auto addAccessor = [&](const void* p, size_t bytes, size_t count, const char* type, int componentType) {
        size_t offset = bin.size();
        put(p, bytes);
        views.push_back({{"buffer", 0}, {"byteOffset", offset}, {"byteLength", bytes}});
        nlohmann::json a = {{"bufferView", views.size() - 1}, {"count", count}, {"type", type}, {"componentType", componentType}};
        accessors.push_back(a);
        return int(accessors.size() - 1);
    };
    for (const Quad& q : quads) {
        float h = q.half;
        float pos[12] = {-h, -h, q.z, h, -h, q.z, h, h, q.z, -h, h, q.z};
        float nz = q.faceDown ? -1.0f : 1.0f;
        float nrm[12] = {0, 0, nz, 0, 0, nz, 0, 0, nz, 0, 0, nz};
        float uv[8] = {0, 1, 1, 1, 1, 0, 0, 0};
        uint16_t idx[6] = {0, 1, 2, 0, 2, 3};
        if (q.faceDown) idx[1] = 2, idx[2] = 1, idx[4] = 3, idx[5] = 2;
        int pa = addAccessor(pos, sizeof pos, 4, "VEC3", 5126);
        accessors[size_t(pa)]["min"] = {-h, -h, q.z};
        accessors[size_t(pa)]["max"] = {h, h, q.z};
        nlohmann::json attrs = {{"POSITION", pa}, {"NORMAL", addAccessor(nrm, sizeof nrm, 4, "VEC3", 5126)},
                                {"TEXCOORD_0", addAccessor(uv, sizeof uv, 4, "VEC2", 5126)}};
        if (q.colors) {
            float c[16];
            for (int i = 0; i < 4; ++i) std::memcpy(c + 4 * i, &q.color, 16);
            attrs["COLOR_0"] = addAccessor(c, sizeof c, 4, "VEC4", 5126);
        }
        if (q.tangents) {
            float t[16];
            for (int i = 0; i < 4; ++i) std::memcpy(t + 4 * i, &q.tangent, 16);
            attrs["TANGENT"] = addAccessor(t, sizeof t, 4, "VEC4", 5126);
        }
        int ia = addAccessor(idx, sizeof idx, 6, "SCALAR", 5123);
        meshes.push_back({{"primitives", {{{"attributes", attrs}, {"indices", ia}, {"material", q.material}}}}});
        nodes.push_back({{"mesh", meshes.size() - 1}});
    }
    nlohmann::json imgs = nlohmann::json::array(), textures = nlohmann::json::array();
    for (size_t i = 0; i < images.size(); ++i) {
        // 8-bit RGBA PNG with the given linear values written as bytes directly (no transfer function).
        const Image& im = images[i];
        std::vector<unsigned char> rgba(size_t(im.width) * size_t(im.height) * 4);
        for (size_t k = 0; k < im.pixels.size(); ++k) {
            for (int c = 0; c < 3; ++c) rgba[4 * k + size_t(c)] = (unsigned char)std::lround(255.0f * im.pixels[k][c]);
            rgba[4 * k + 3] = alphas.size() > i && !alphas[i].empty() ? alphas[i][k] : 255;
        }
        std::string png = name + "-" + std::to_string(i) + ".png";
        // PNG through the project's writer would sRGB-encode; write a minimal uncompressed one instead.
        writePng(dir + "/" + png, im.width, im.height, 4, rgba);
        imgs.push_back({{"uri", png}});
        textures.push_back({{"source", i}, {"sampler", 0}});
    }
    nlohmann::json root = {{"asset", {{"version", "2.0"}}},
                           {"scene", 0},
                           {"scenes", {{{"nodes", nlohmann::json::array()}}}},
                           {"nodes", nodes},
                           {"meshes", meshes},
                           {"materials", materials},
                           {"buffers", {{{"uri", name + ".bin"}, {"byteLength", bin.size()}}}},
                           {"bufferViews", views},
                           {"accessors", accessors}};
    for (size_t n = 0; n < nodes.size(); ++n) root["scenes"][0]["nodes"].push_back(n);
    if (!images.empty()) {
        root["images"] = imgs;
        root["textures"] = textures;
        root["samplers"] = {{{"magFilter", 9728}, {"minFilter", 9728}}};
        root["extensionsUsed"] = {"KHR_texture_transform"};
    }
    std::ofstream(dir + "/" + name + ".bin", std::ios::binary).write(reinterpret_cast<const char*>(bin.data()), std::streamsize(bin.size()));
    std::ofstream(dir + "/" + name + ".gltf") << root.dump(1);
    return dir + "/" + name + ".gltf";
}

Image solid(int w, int h, glm::vec3 c) {
    Image im(w, h);
    for (glm::vec3& p : im.pixels) p = c;
    return im;
}

// Renders the scene from a camera at `eye` looking down -Z (perspective, vertical field of view `fov`) under
// the directional lights given, and returns the mean over the image.
glm::dvec3 renderMean(Scene& scene, glm::vec3 eye, float fov, int size, int spp, int maxDepth = 0) {
    scene.updateBounds();
    Accel accel(scene);
    LightSampler lights(scene);
    PathTracer tracer(scene, accel, lights);
    Camera camera;
    camera.position = eye;
    camera.yfov = fov;
    RenderSettings s;
    s.width = s.height = size;
    s.spp = spp;
    s.maxDepth = maxDepth;
    s.seed = 3;
    return tracer.render(camera, s).mean();
}

PunctualLight sunFrom(glm::vec3 towardsLight, float irradiance) {
    PunctualLight l;
    l.type = PunctualLight::Type::Directional;
    l.direction = -glm::normalize(towardsLight);
    l.intensity = glm::vec3(irradiance);
    return l;
}

nlohmann::json lambertian(float albedo) {
    return {{"pbrMetallicRoughness", {{"baseColorFactor", {albedo, albedo, albedo, 1.0}}, {"metallicFactor", 0.0}}},
            {"extensions", {{"KHR_materials_specular", {{"specularFactor", 0.0}}}}}};
}

// A normal-mapped plane lit by a directional light: radiance (a / pi) E max(0, n . l), n the perturbed normal
// in the tangent frame (T, B = w N x T, N), for lights from several directions (so both tangent axes and
// their signs are checked).
TEST(MaterialFeatures, NormalMappedPlaneShadesWithThePerturbedNormal) {
    ThreadScope threads(0);
    const std::string dir = testing::TempDir();
    const glm::vec3 bytes(166.0f, 140.0f, 240.0f);
    const glm::vec3 t = 2.0f * bytes / 255.0f - 1.0f;
    struct Case {
        const char* name;
        bool tangents;
        glm::vec4 tangent;
        glm::vec3 T, B;  // expected world tangent frame
    };
    for (const Case& c : {Case{"generated", false, {}, {1, 0, 0}, {0, 1, 0}},
                          Case{"given", true, {0, 1, 0, 1}, {0, 1, 0}, {-1, 0, 0}},
                          Case{"given-flipped", true, {0, 1, 0, -1}, {0, 1, 0}, {1, 0, 0}}}) {
        nlohmann::json m = lambertian(0.6f);
        m["normalTexture"] = {{"index", 0}, {"scale", 1.0}};
        Quad q;
        q.half = 4.0f;
        q.tangents = c.tangents;
        q.tangent = c.tangent;
        std::string path = writeGltf(dir, std::string("normal-") + c.name, {q}, nlohmann::json::array({m}), {solid(1, 1, bytes / 255.0f)});
        Scene scene = loadGltf(path);
        ASSERT_EQ(scene.stats.primitivesWithGeneratedTangents, c.tangents ? 0u : 1u);
        glm::vec3 n = glm::normalize(t.x * c.T + t.y * c.B + t.z * glm::vec3(0, 0, 1));
        for (glm::vec3 towards : {glm::vec3(0, 0, 1), glm::vec3(1, 0, 1), glm::vec3(0, 1, 1), glm::vec3(-1, -0.5f, 1)}) {
            scene.lights = {sunFrom(towards, 2.0f)};
            glm::dvec3 mean = renderMean(scene, {0, 0, 1}, 0.5f, 8, 4);
            double expected = 0.6 / kPi * 2.0 * std::max(0.0f, glm::dot(n, glm::normalize(towards)));
            EXPECT_NEAR(mean.x / expected, 1.0, 1e-4) << c.name << " light from " << towards.x << "," << towards.y;
        }
    }
}

// An occluder at z = 1 with a checkerboard alpha (MASK, cutoff 0.5) over a floor lit from straight above:
// the floor under it receives exactly half the light; a BLEND occluder of uniform alpha 0.3 passes 70% of it.
TEST(MaterialFeatures, AlphaCutoutsAndBlendPassTheExpectedFractionOfLight) {
    ThreadScope threads(0);
    const std::string dir = testing::TempDir();
    Image checker(8, 8);
    std::vector<uint8_t> alpha(64);
    for (int y = 0; y < 8; ++y)
        for (int x = 0; x < 8; ++x) {
            checker.at(x, y) = glm::vec3(1.0f);
            alpha[size_t(y * 8 + x)] = (x + y) % 2 ? 255 : 0;
        }
    nlohmann::json floor = lambertian(0.5f);
    nlohmann::json mask = lambertian(0.5f);
    mask["alphaMode"] = "MASK";
    mask["pbrMetallicRoughness"]["baseColorTexture"] = {{"index", 0}};
    nlohmann::json blend = lambertian(0.5f);
    blend["alphaMode"] = "BLEND";
    blend["pbrMetallicRoughness"]["baseColorFactor"] = {0.5, 0.5, 0.5, 0.3};
    Quad floorQuad;
    floorQuad.half = 1.0f;
    Quad occluder;
    occluder.z = 1.0f;
    occluder.half = 1.0f;
    occluder.faceDown = true;
    // The camera at z = 0.5 sees exactly the floor's [-1, 1]^2 (tan(fov / 2) = 1 / 0.5), not the occluder.
    const float fov = 2.0f * std::atan(2.0f);
    const double lit = 0.5 / kPi * 3.0;
    {
        occluder.material = 1;
        Scene scene = loadGltf(writeGltf(dir, "mask", {floorQuad, occluder}, {floor, mask}, {checker}, {alpha}));
        ASSERT_EQ(scene.materials[1].alphaMode, Material::AlphaMode::Mask);
        scene.lights = {sunFrom({0, 0, 1}, 3.0f)};
        glm::dvec3 mean = renderMean(scene, {0, 0, 0.5f}, fov, 64, 16, 2);
        EXPECT_NEAR(mean.x / lit, 0.5, 0.01);
        // Opaque, the same occluder blocks everything.
        scene.materials[1].alphaMode = Material::AlphaMode::Opaque;
        EXPECT_EQ(renderMean(scene, {0, 0, 0.5f}, fov, 16, 4, 2).x, 0.0);
    }
    {
        occluder.material = 1;
        Scene scene = loadGltf(writeGltf(dir, "blend", {floorQuad, occluder}, {floor, blend}));
        ASSERT_EQ(scene.materials[1].alphaMode, Material::AlphaMode::Blend);
        EXPECT_FLOAT_EQ(scene.materials[1].alpha, 0.3f);
        scene.lights = {sunFrom({0, 0, 1}, 3.0f)};
        glm::dvec3 mean = renderMean(scene, {0, 0, 0.5f}, fov, 64, 16, 2);
        EXPECT_NEAR(mean.x / lit, 0.7, 0.01);
    }
}

// COLOR_0 multiplies the base colour; KHR_texture_transform's offset, rotation and scale move the texture as
// the extension's matrix says.
TEST(MaterialFeatures, VertexColoursAndTextureTransforms) {
    const std::string dir = testing::TempDir();
    // A 2 x 1 texture: left texel red, right texel green.
    Image tex(2, 1);
    tex.at(0, 0) = glm::vec3(1, 0, 0);
    tex.at(1, 0) = glm::vec3(0, 1, 0);
    nlohmann::json m = lambertian(1.0f);
    m["pbrMetallicRoughness"]["baseColorTexture"] = {
        {"index", 0}, {"extensions", {{"KHR_texture_transform", {{"offset", {0.5, 0.0}}, {"scale", {1.0, 1.0}}}}}}};
    Quad q;
    q.colors = true;
    q.color = glm::vec4(0.5f, 0.25f, 1.0f, 1.0f);
    Scene scene = loadGltf(writeGltf(dir, "transform", {q}, nlohmann::json::array({m}), {tex}));
    ASSERT_EQ(scene.mesh.colors.size(), scene.mesh.positions.size());
    const TextureRef& ref = scene.materials[0].baseColorTexture;
    EXPECT_EQ(ref.offset, glm::vec2(0.5f, 0.0f));
    // The matrix of the spec: offset + R(rotation) (scale * uv), R = [cos sin; -sin cos].
    TextureRef r;
    r.offset = {0.5f, 0.0f};
    r.rotation = float(kPi / 2);
    r.scale = {2.0f, 1.0f};
    glm::vec2 moved = r.apply({1.0f, 0.0f});
    EXPECT_NEAR(moved.x, 0.5f, 1e-6f);
    EXPECT_NEAR(moved.y, -2.0f, 1e-6f);
    // At u = 0.25 (the left texel untransformed) the offset of 0.5 reads the right texel: green, times COLOR_0.
    Accel accel(scene);
    Hit hit = accel.intersect({-0.5f, 0.0f, 1.0f}, {0, 0, -1});
    ASSERT_TRUE(hit.valid());
    SurfaceInteraction si = makeInteraction(scene, hit, {0, 0, -1});
    EXPECT_NEAR(si.bsdf.baseColor.x, 0.0f, 1e-6f);
    EXPECT_NEAR(si.bsdf.baseColor.y, 0.25f, 1e-6f);
    EXPECT_NEAR(si.bsdf.baseColor.z, 0.0f, 1e-6f);
}

// Every 8-bit value decodes as the transfer functions say, bit for bit, from PNGs of every channel count:
// colour textures through sRGB (srgbToLinear(v / 255)), data textures and alpha linearly (v / 255), grey
// spread to RGB (tinygltf hands 8-bit images over as RGBA; the loader converts bytes through tables).
TEST(MaterialFeatures, EveryByteDecodesAsItsTransferFunctionSays) {
    const std::string dir = testing::TempDir();
    Image ramp(256, 1);
    std::vector<uint8_t> alpha(256);
    for (int v = 0; v < 256; ++v) {
        ramp.at(v, 0) = glm::vec3(float(v) / 255.0f, float(255 - v) / 255.0f, float(v) / 255.0f);
        alpha[size_t(v)] = uint8_t(255 - v);
    }
    // Textures 0, 1: RGBA (colour, data); 2: grey (colour); 3: grey and alpha (data); 4: RGB (colour).
    nlohmann::json rgba = lambertian(1.0f), grey = lambertian(1.0f), rgb = lambertian(1.0f);
    rgba["pbrMetallicRoughness"]["baseColorTexture"] = {{"index", 0}};
    rgba["pbrMetallicRoughness"]["metallicRoughnessTexture"] = {{"index", 1}};
    grey["pbrMetallicRoughness"]["baseColorTexture"] = {{"index", 2}};
    grey["pbrMetallicRoughness"]["metallicRoughnessTexture"] = {{"index", 3}};
    rgb["pbrMetallicRoughness"]["baseColorTexture"] = {{"index", 4}};
    Quad q0, q1, q2;
    q1.material = 1;
    q1.z = 1.0f;
    q2.material = 2;
    q2.z = 2.0f;
    const std::string path = writeGltf(dir, "bytes", {q0, q1, q2}, nlohmann::json::array({rgba, grey, rgb}),
                                       {ramp, ramp, ramp, ramp, ramp}, {alpha, alpha, alpha, alpha, alpha});
    // Images 2-4 rewritten with fewer channels (the same file names).
    std::vector<unsigned char> g(256), ga(512), c3(768);
    for (int v = 0; v < 256; ++v) {
        g[size_t(v)] = uint8_t(v);
        ga[2 * size_t(v)] = uint8_t(v);
        ga[2 * size_t(v) + 1] = uint8_t(255 - v);
        c3[3 * size_t(v)] = uint8_t(v);
        c3[3 * size_t(v) + 1] = uint8_t(255 - v);
        c3[3 * size_t(v) + 2] = uint8_t(v);
    }
    writePng(dir + "/bytes-2.png", 256, 1, 1, g);
    writePng(dir + "/bytes-3.png", 256, 1, 2, ga);
    writePng(dir + "/bytes-4.png", 256, 1, 3, c3);
    Scene scene = loadGltf(path);
    auto texture = [&](const TextureRef& ref) -> const Texture& { return scene.textures[size_t(ref.texture)]; };
    const Texture& colour4 = texture(scene.materials[0].baseColorTexture);
    const Texture& data4 = texture(scene.materials[0].metallicRoughnessTexture);
    const Texture& colour1 = texture(scene.materials[1].baseColorTexture);
    const Texture& data2 = texture(scene.materials[1].metallicRoughnessTexture);
    const Texture& colour3 = texture(scene.materials[2].baseColorTexture);
    for (const Texture* t : {&colour4, &data4, &colour1, &data2, &colour3}) ASSERT_EQ(t->texelCount(), 256u);
    for (int v = 0; v < 256; ++v) {
        const float u = float(v) / 255.0f, w = float(255 - v) / 255.0f;
        const float cu = srgbToLinear(u), cw = srgbToLinear(w);
        ASSERT_EQ(colour4.texel(size_t(v)), glm::vec4(cu, cw, cu, w)) << v;
        ASSERT_EQ(data4.texel(size_t(v)), glm::vec4(u, w, u, w)) << v;
        ASSERT_EQ(colour1.texel(size_t(v)), glm::vec4(cu, cu, cu, 1.0f)) << v;
        ASSERT_EQ(data2.texel(size_t(v)), glm::vec4(u, u, u, w)) << v;
        ASSERT_EQ(colour3.texel(size_t(v)), glm::vec4(cu, cw, cu, 1.0f)) << v;
    }
}

// KHR_materials_transmission (thin-walled): a Lambertian floor of albedo a under a clear, smooth, fully
// transmissive sheet, all under a uniform sky of radiance 1, reflects a (less the sheet's GGX
// single-scattering loss, < 1%); the same sheet opaque (a white Lambertian) lets the floor see far less sky.
TEST(MaterialFeatures, ThinTransmissionPassesTheSky) {
    ThreadScope threads(0);
    const std::string dir = testing::TempDir();
    nlohmann::json floor = lambertian(0.5f);
    nlohmann::json glass = lambertian(1.0f);
    glass["pbrMetallicRoughness"]["roughnessFactor"] = 0.05;
    glass["extensions"]["KHR_materials_transmission"] = {{"transmissionFactor", 1.0}};
    Quad floorQuad;
    floorQuad.half = 1.0f;
    Quad sheet;
    sheet.z = 0.5f;
    sheet.half = 50.0f;  // covers the floor's whole sky
    sheet.material = 1;
    Scene scene = loadGltf(writeGltf(dir, "glass", {floorQuad, sheet}, {floor, glass}));
    ASSERT_EQ(scene.materials[1].transmission, 1.0f);
    for (const std::string& w : scene.stats.warnings) EXPECT_EQ(w.find("transmission"), std::string::npos) << w;
    scene.environment = defaultSky();
    // The camera between floor and sheet sees only the floor.
    const float fov = 2.0f * std::atan(2.0f * 0.8f);
    glm::dvec3 clear = renderMean(scene, {0, 0, 0.25f}, fov, 16, 256);
    EXPECT_NEAR(clear.x / 0.5, 1.0, 0.015);
    scene.materials[1].transmission = 0.0f;
    glm::dvec3 opaque = renderMean(scene, {0, 0, 0.25f}, fov, 16, 64);
    EXPECT_LT(opaque.x, 0.6 * clear.x);
}

}  // namespace
}  // namespace nrad
