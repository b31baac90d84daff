// glTF 2.0 import through tinygltf (with Draco). Validates every index and byte range it reads, so a
// malformed file becomes a SceneError naming the file, never undefined behaviour.
#include "baker/scene/gltf_loader.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstring>
#include <fstream>
#include <map>
#include <limits>
#include <set>
#include <sstream>
#include <string_view>

#include <sys/stat.h>

#include <draco/compression/decode.h>
#include <glm/gtc/matrix_transform.hpp>
#include <glm/gtc/quaternion.hpp>
#include <glm/gtc/type_ptr.hpp>
#include <nlohmann/json.hpp>
#include <stb_image.h>
#include <tiny_gltf.h>

namespace nrad {

namespace {

constexpr int kMaxNodeDepth = 1024;

const std::set<std::string>& supportedExtensions() {
    static const std::set<std::string> s = {
        "KHR_draco_mesh_compression", "KHR_materials_emissive_strength", "KHR_lights_punctual",
        "KHR_materials_specular", "KHR_mesh_quantization", "KHR_texture_transform", "KHR_materials_ior",
        "KHR_materials_transmission"};
    return s;
}

// An integer read from a JSON number a file gave: a value outside int's range (or not a number) becomes
// `invalid`, never the undefined behaviour of converting it; the caller refuses it by its range check.
int toInt(double v, int invalid) {
    if (!(v >= double(std::numeric_limits<int>::min()) && v <= double(std::numeric_limits<int>::max()))) return invalid;
    return int(v);
}

std::string trim(std::string s) {
    while (!s.empty() && (s.back() == '\n' || s.back() == ' ' || s.back() == '\r')) s.pop_back();
    return s;
}

class Importer {
public:
    Importer(const std::string& path, tinygltf::Model& model, const ImportLimits& limits, Scene& scene)
        : path_(path), model_(model), limits_(limits), scene_(scene) {}

    [[noreturn]] void fail(const std::string& what) const { throw SceneError(path_ + ": " + what); }
    void warn(const std::string& what) { scene_.stats.warnings.push_back(what); }

    void run() {
        for (const std::string& ext : model_.extensionsRequired)
            if (!supportedExtensions().count(ext))
                fail("requires extension " + ext + ", which nrad does not support");
        for (const std::string& ext : model_.extensionsUsed)
            if (!supportedExtensions().count(ext))
                warn("extension " + ext + " is used but not supported; it is ignored");

        importMaterials();
        importLights();
        defaultMaterial_ = -1;

        std::vector<int> roots;
        if (!model_.scenes.empty()) {
            int s = model_.defaultScene >= 0 ? model_.defaultScene : 0;
            if (s >= int(model_.scenes.size())) fail("default scene " + std::to_string(s) + " does not exist");
            roots = model_.scenes[size_t(s)].nodes;
        } else {
            // No scenes: render every node that is nobody's child.
            std::vector<bool> isChild(model_.nodes.size(), false);
            for (const tinygltf::Node& n : model_.nodes)
                for (int c : n.children)
                    if (c >= 0 && size_t(c) < isChild.size()) isChild[size_t(c)] = true;
            for (size_t i = 0; i < model_.nodes.size(); ++i)
                if (!isChild[i]) roots.push_back(int(i));
        }
        checkNodeGraph(roots);
        std::vector<int> stack;
        for (int r : roots) visitNode(r, glm::dmat4(1.0), stack);

        if (scene_.materials.empty()) scene_.materials.push_back(defaultMaterial());
        scene_.updateBounds();
    }

private:
    // ----- materials and textures -----

    static Material defaultMaterial() {
        Material m;  // glTF defaults: white, metallic 1, roughness 1
        m.name = "default";
        return m;
    }

    int materialIndexFor(int gltfMaterial) {
        if (gltfMaterial >= 0) {
            if (size_t(gltfMaterial) >= model_.materials.size())
                fail("primitive refers to material " + std::to_string(gltfMaterial) + ", but there are only " +
                     std::to_string(model_.materials.size()));
            return gltfMaterial;
        }
        if (defaultMaterial_ < 0) {
            defaultMaterial_ = int(scene_.materials.size());
            scene_.materials.push_back(defaultMaterial());
        }
        return defaultMaterial_;
    }

    static double number(const tinygltf::Value& obj, const char* key, double fallback) {
        if (!obj.IsObject() || !obj.Has(key)) return fallback;
        const tinygltf::Value& v = obj.Get(key);
        return v.IsNumber() ? v.GetNumberAsDouble() : fallback;
    }

    // KHR_texture_transform of a texture slot (its texCoord override included).
    TextureRef transformed(TextureRef ref, const tinygltf::ExtensionMap& extensions, const std::string& where) {
        auto it = extensions.find("KHR_texture_transform");
        if (!ref.valid() || it == extensions.end()) return ref;
        const tinygltf::Value& t = it->second;
        auto pair = [&](const char* key, glm::vec2 fallback) {
            if (!t.Has(key)) return fallback;
            const tinygltf::Value& v = t.Get(key);
            if (!v.IsArray() || v.ArrayLen() != 2 || !v.Get(0).IsNumber() || !v.Get(1).IsNumber())
                fail(where + ": KHR_texture_transform " + key + " must be two numbers");
            return glm::vec2(float(v.Get(0).GetNumberAsDouble()), float(v.Get(1).GetNumberAsDouble()));
        };
        ref.offset = pair("offset", glm::vec2(0.0f));
        ref.scale = pair("scale", glm::vec2(1.0f));
        ref.rotation = float(number(t, "rotation", 0.0));
        if (!std::isfinite(ref.offset.x) || !std::isfinite(ref.offset.y) || !std::isfinite(ref.scale.x) ||
            !std::isfinite(ref.scale.y) || !std::isfinite(ref.rotation))
            fail(where + ": KHR_texture_transform has a non-finite value");
        if (t.Has("texCoord")) {
            int tc = toInt(number(t, "texCoord", 0.0), -1);
            if (tc == 0 || tc == 1)
                ref.texCoord = tc;
            else
                warn(where + ": KHR_texture_transform texCoord " + std::to_string(tc) + " is not read; using " + std::to_string(ref.texCoord));
        }
        return ref;
    }

    TextureRef textureRef(int textureIndex, int texCoord, bool srgb, const std::string& where) {
        if (textureIndex < 0) return {};
        if (size_t(textureIndex) >= model_.textures.size())
            fail(where + " refers to texture " + std::to_string(textureIndex) + ", but there are only " +
                 std::to_string(model_.textures.size()));
        if (texCoord < 0 || texCoord > 1) {
            warn(where + " uses TEXCOORD_" + std::to_string(texCoord) + "; only sets 0 and 1 are read, using 0");
            texCoord = 0;
        }
        auto key = std::make_pair(textureIndex, srgb);
        auto it = textureCache_.find(key);
        if (it != textureCache_.end()) return {it->second, texCoord};

        const tinygltf::Texture& t = model_.textures[size_t(textureIndex)];
        if (t.source < 0 || size_t(t.source) >= model_.images.size())
            fail("texture " + std::to_string(textureIndex) + " has no valid image source");
        const tinygltf::Image& img = model_.images[size_t(t.source)];
        Texture tex;
        if (img.width <= 0 || img.height <= 0 || img.image.empty()) {
            // A missing or undecodable image is an error, not a white texture: the scene would render wrong.
            fail("image " + std::to_string(t.source) + (img.uri.empty() || img.uri.rfind("data:", 0) == 0 ? std::string() : " (" + img.uri + ")") +
                 " is missing or is not a decodable PNG/JPEG");
        } else {
            tex.width = img.width;
            tex.height = img.height;
            int comp = img.component, bytes = img.bits / 8;
            if (comp < 1 || comp > 4 || (bytes != 1 && bytes != 2) ||
                uint64_t(img.width) * uint64_t(img.height) > limits_.maxTexturePixels ||
                img.image.size() / (size_t(comp) * size_t(bytes)) / size_t(img.width) < size_t(img.height))
                fail("image " + std::to_string(t.source) + " has an unsupported pixel layout");
            const size_t count = size_t(img.width) * size_t(img.height);
            if (bytes == 1) {
                // 8-bit channels kept as RGBA bytes, decoded in lookups through tables of the same conversions
                // as below (Texture::texel): colour from sRGB where the texture holds colour, alpha (a 2- or
                // 4-channel image's last) always linear. (tinygltf expands 8-bit images to RGBA unless told to
                // preserve their channels; the other counts are for when it does.)
                tex.colour = srgb ? linearOfSrgbByte() : unitOfByte();
                tex.alpha = unitOfByte();
                tex.bytes.resize(4 * count);
                const unsigned char* px = img.image.data();
                uint8_t* out = tex.bytes.data();
                for (size_t i = 0; i < count; ++i, px += comp, out += 4) {
                    switch (comp) {
                        case 1: out[0] = out[1] = out[2] = px[0], out[3] = 255; break;
                        case 2: out[0] = out[1] = out[2] = px[0], out[3] = px[1]; break;
                        case 3: out[0] = px[0], out[1] = px[1], out[2] = px[2], out[3] = 255; break;
                        default: out[0] = px[0], out[1] = px[1], out[2] = px[2], out[3] = px[3]; break;
                    }
                }
            } else {
                tex.texels.resize(count);
                for (size_t i = 0; i < tex.texels.size(); ++i) {
                    float c[4] = {0, 0, 0, 1};
                    for (int k = 0; k < comp; ++k) {
                        size_t off = (i * size_t(comp) + size_t(k)) * 2;
                        c[k] = float(uint16_t(img.image[off] | (img.image[off + 1] << 8))) / 65535.0f;
                    }
                    if (comp == 1) c[1] = c[2] = c[0];
                    if (comp == 2) { c[3] = c[1]; c[1] = c[2] = c[0]; }
                    if (srgb)
                        for (int k = 0; k < 3; ++k) c[k] = srgbToLinear(c[k]);
                    tex.texels[i] = glm::vec4(c[0], c[1], c[2], c[3]);
                }
            }
        }
        if (t.sampler >= 0 && size_t(t.sampler) < model_.samplers.size()) {
            auto wrap = [](int w) {
                return w == TINYGLTF_TEXTURE_WRAP_CLAMP_TO_EDGE     ? WrapMode::ClampToEdge
                       : w == TINYGLTF_TEXTURE_WRAP_MIRRORED_REPEAT ? WrapMode::MirroredRepeat
                                                                    : WrapMode::Repeat;
            };
            tex.wrapS = wrap(model_.samplers[size_t(t.sampler)].wrapS);
            tex.wrapT = wrap(model_.samplers[size_t(t.sampler)].wrapT);
        }
        tex.computeAverage();
        int index = int(scene_.textures.size());
        scene_.textures.push_back(std::move(tex));
        textureCache_[key] = index;
        return {index, texCoord};
    }

    static bool finite3(const glm::vec3& v) { return std::isfinite(v.x) && std::isfinite(v.y) && std::isfinite(v.z); }

    void importMaterials() {
        for (size_t i = 0; i < model_.materials.size(); ++i) {
            const tinygltf::Material& gm = model_.materials[i];
            const std::string where = "material " + std::to_string(i) + " (" + gm.name + ")";
            Material m;
            m.name = gm.name;
            const auto& pbr = gm.pbrMetallicRoughness;
            if (pbr.baseColorFactor.size() >= 3)
                m.baseColor = glm::vec3(pbr.baseColorFactor[0], pbr.baseColorFactor[1], pbr.baseColorFactor[2]);
            m.baseColorTexture = transformed(textureRef(pbr.baseColorTexture.index, pbr.baseColorTexture.texCoord, true, where),
                                             pbr.baseColorTexture.extensions, where);
            if (pbr.baseColorFactor.size() >= 4) m.alpha = float(pbr.baseColorFactor[3]);
            if (gm.alphaMode == "MASK")
                m.alphaMode = Material::AlphaMode::Mask;
            else if (gm.alphaMode == "BLEND")
                m.alphaMode = Material::AlphaMode::Blend;
            else if (gm.alphaMode != "OPAQUE" && !gm.alphaMode.empty())
                fail(where + ": alphaMode '" + gm.alphaMode + "' is not OPAQUE, MASK or BLEND");
            m.alphaCutoff = float(gm.alphaCutoff);
            if (!std::isfinite(m.alpha) || !std::isfinite(m.alphaCutoff)) fail(where + " has a non-finite alpha or alphaCutoff");
            m.alpha = std::clamp(m.alpha, 0.0f, 1.0f);
            m.normalTexture = transformed(textureRef(gm.normalTexture.index, gm.normalTexture.texCoord, false, where),
                                          gm.normalTexture.extensions, where);
            m.normalScale = float(gm.normalTexture.scale);
            if (!std::isfinite(m.normalScale)) fail(where + " has a non-finite normalTexture scale");
            m.metallic = float(pbr.metallicFactor);
            m.roughness = float(pbr.roughnessFactor);
            m.metallicRoughnessTexture = transformed(textureRef(pbr.metallicRoughnessTexture.index,
                                                                pbr.metallicRoughnessTexture.texCoord, false, where),
                                                     pbr.metallicRoughnessTexture.extensions, where);
            float strength = 1.0f;
            auto es = gm.extensions.find("KHR_materials_emissive_strength");
            if (es != gm.extensions.end()) strength = float(number(es->second, "emissiveStrength", 1.0));
            if (gm.emissiveFactor.size() >= 3)
                m.emission = strength * glm::vec3(gm.emissiveFactor[0], gm.emissiveFactor[1], gm.emissiveFactor[2]);
            m.emissiveTexture = transformed(textureRef(gm.emissiveTexture.index, gm.emissiveTexture.texCoord, true, where),
                                            gm.emissiveTexture.extensions, where);
            auto sp = gm.extensions.find("KHR_materials_specular");
            if (sp != gm.extensions.end()) {
                m.specular = float(number(sp->second, "specularFactor", 1.0));
                if (sp->second.Has("specularColorFactor")) {
                    const tinygltf::Value& c = sp->second.Get("specularColorFactor");
                    if (c.IsArray() && c.ArrayLen() == 3)
                        for (int k = 0; k < 3; ++k) m.specularColor[k] = float(c.Get(k).GetNumberAsDouble());
                }
                if (sp->second.Has("specularTexture") || sp->second.Has("specularColorTexture"))
                    warn(where + ": KHR_materials_specular textures are ignored (factors are used)");
            }
            auto tr = gm.extensions.find("KHR_materials_transmission");
            if (tr != gm.extensions.end()) {
                m.transmission = float(number(tr->second, "transmissionFactor", 0.0));
                if (tr->second.Has("transmissionTexture")) {
                    const tinygltf::Value& t = tr->second.Get("transmissionTexture");
                    int index = toInt(number(t, "index", -1.0), std::numeric_limits<int>::max());
                    int texCoord = toInt(number(t, "texCoord", 0.0), -1);
                    tinygltf::ExtensionMap ext;
                    if (t.Has("extensions") && t.Get("extensions").Has("KHR_texture_transform"))
                        ext["KHR_texture_transform"] = t.Get("extensions").Get("KHR_texture_transform");
                    m.transmissionTexture = transformed(textureRef(index, texCoord, false, where), ext, where);
                }
                if (!std::isfinite(m.transmission)) fail(where + " has a non-finite transmissionFactor");
                m.transmission = std::clamp(m.transmission, 0.0f, 1.0f);
            }
            auto ior = gm.extensions.find("KHR_materials_ior");
            if (ior != gm.extensions.end()) m.ior = float(number(ior->second, "ior", 1.5));
            m.doubleSided = gm.doubleSided;
            if (!finite3(m.baseColor) || !finite3(m.emission) || !std::isfinite(m.metallic) ||
                !std::isfinite(m.roughness) || !std::isfinite(m.specular) || !finite3(m.specularColor))
                fail(where + " has a non-finite factor");
            if (glm::any(glm::lessThan(m.emission, glm::vec3(0.0f))))
                fail(where + " has a negative emissive factor or strength");
            m.baseColor = glm::clamp(m.baseColor, 0.0f, 1.0f);
            m.metallic = glm::clamp(m.metallic, 0.0f, 1.0f);
            m.roughness = glm::clamp(m.roughness, 0.0f, 1.0f);
            m.specular = glm::clamp(m.specular, 0.0f, 1.0f);
            m.specularColor = glm::max(m.specularColor, glm::vec3(0.0f));
            scene_.materials.push_back(m);
        }
    }

    // ----- lights -----

    void importLights() {
        // The light definitions; instances are created per node in visitNode.
        for (size_t i = 0; i < model_.lights.size(); ++i) {
            const tinygltf::Light& l = model_.lights[i];
            if (l.type != "point" && l.type != "spot" && l.type != "directional")
                fail("light " + std::to_string(i) + " has unknown type '" + l.type + "'");
            if (!std::isfinite(l.intensity) || l.intensity < 0.0)
                fail("light " + std::to_string(i) + " has an invalid intensity");
        }
    }

    void addLightInstance(int index, const glm::dmat4& worldFromNode) {
        if (index < 0 || size_t(index) >= model_.lights.size())
            fail("node refers to light " + std::to_string(index) + ", but there are only " +
                 std::to_string(model_.lights.size()));
        const tinygltf::Light& l = model_.lights[size_t(index)];
        PunctualLight light;
        light.name = l.name;
        glm::vec3 color(1.0f);
        if (l.color.size() >= 3) color = glm::vec3(l.color[0], l.color[1], l.color[2]);
        // Point and spot: candela (lm/sr) -> W/sr. Directional: lux (lm/m^2) -> W/m^2.
        light.intensity = color * float(l.intensity) / kLumensPerWatt;
        light.position = glm::vec3(worldFromNode * glm::dvec4(0, 0, 0, 1));
        light.direction = glm::normalize(glm::vec3(worldFromNode * glm::dvec4(0, 0, -1, 0)));
        if (l.type == "point") {
            light.type = PunctualLight::Type::Point;
        } else if (l.type == "spot") {
            light.type = PunctualLight::Type::Spot;
            double outer = std::clamp(l.spot.outerConeAngle, 0.0, M_PI / 2);
            double inner = std::clamp(l.spot.innerConeAngle, 0.0, outer);
            light.cosOuterCone = float(std::cos(outer));
            light.cosInnerCone = float(std::cos(inner));
        } else {
            light.type = PunctualLight::Type::Directional;
        }
        if (!finite3(light.position) || !finite3(light.direction) || !finite3(light.intensity))
            fail("light " + std::to_string(index) + " has a non-finite transform or colour");
        scene_.lights.push_back(light);
    }

    // ----- nodes -----

    // glTF's node hierarchy is a set of disjoint trees: a node has at most one parent, and a scene's roots are
    // nobody's children, each listed once. A file that breaks this describes a graph whose flattening can
    // grow as 2^depth (a node listed twice as a child, 30 levels deep: 2^29 instances), so it is refused here,
    // before anything is instanced.
    void checkNodeGraph(const std::vector<int>& roots) const {
        const size_t count = model_.nodes.size();
        std::vector<int> parent(count, -1);
        for (size_t i = 0; i < count; ++i)
            for (int c : model_.nodes[i].children) {
                if (c < 0 || size_t(c) >= count)
                    fail("node " + std::to_string(i) + " lists child " + std::to_string(c) + ", which does not exist (there are " +
                         std::to_string(count) + " nodes)");
                if (size_t(c) == i) fail("node " + std::to_string(i) + " is its own child (cycle in the node hierarchy)");
                if (parent[size_t(c)] >= 0)
                    fail("node " + std::to_string(c) + " has two parents (it is a child of nodes " +
                         std::to_string(parent[size_t(c)]) + " and " + std::to_string(i) +
                         "); glTF node hierarchies must be trees");
                parent[size_t(c)] = int(i);
            }
        std::vector<bool> isRoot(count, false);
        for (int r : roots) {
            if (r < 0 || size_t(r) >= count)
                fail("node " + std::to_string(r) + " does not exist (there are " + std::to_string(count) + ")");
            if (isRoot[size_t(r)]) fail("the scene lists node " + std::to_string(r) + " twice");
            if (parent[size_t(r)] >= 0)
                fail("node " + std::to_string(r) + " is a root of the scene and a child of node " +
                     std::to_string(parent[size_t(r)]) + "; glTF node hierarchies must be trees");
            isRoot[size_t(r)] = true;
        }
    }

    static glm::dmat4 localTransform(const tinygltf::Node& n) {
        if (n.matrix.size() == 16) return glm::make_mat4(n.matrix.data());
        glm::dmat4 m(1.0);
        if (n.translation.size() == 3) m = glm::translate(m, glm::dvec3(n.translation[0], n.translation[1], n.translation[2]));
        if (n.rotation.size() == 4) {
            glm::dquat q(n.rotation[3], n.rotation[0], n.rotation[1], n.rotation[2]);  // glTF order is x, y, z, w
            m = m * glm::mat4_cast(glm::normalize(q));
        }
        if (n.scale.size() == 3) m = glm::scale(m, glm::dvec3(n.scale[0], n.scale[1], n.scale[2]));
        return m;
    }

    void visitNode(int index, const glm::dmat4& parent, std::vector<int>& stack) {
        if (index < 0 || size_t(index) >= model_.nodes.size())
            fail("node " + std::to_string(index) + " does not exist (there are " + std::to_string(model_.nodes.size()) + ")");
        if (std::find(stack.begin(), stack.end(), index) != stack.end())
            fail("node " + std::to_string(index) + " is its own ancestor (cycle in the node hierarchy)");
        if (stack.size() > size_t(kMaxNodeDepth)) fail("node hierarchy deeper than " + std::to_string(kMaxNodeDepth));
        const tinygltf::Node& node = model_.nodes[size_t(index)];
        glm::dmat4 world = parent * localTransform(node);
        for (int c = 0; c < 4; ++c)
            for (int r = 0; r < 4; ++r)
                if (!std::isfinite(world[c][r])) fail("node " + std::to_string(index) + " has a non-finite transform");
        ++scene_.stats.nodesVisited;
        stack.push_back(index);

        if (node.mesh >= 0) importMeshInstance(node.mesh, world);
        if (node.camera >= 0) addCamera(node.camera, world);
        auto lp = node.extensions.find("KHR_lights_punctual");
        if (lp != node.extensions.end() && lp->second.Has("light"))
            addLightInstance(lp->second.Get("light").IsNumber() ? toInt(lp->second.Get("light").GetNumberAsDouble(), -1) : -1,
                             world);
        for (int child : node.children) visitNode(child, world, stack);
        stack.pop_back();
    }

    void addCamera(int index, const glm::dmat4& world) {
        if (size_t(index) >= model_.cameras.size()) fail("node refers to camera " + std::to_string(index) + ", which does not exist");
        const tinygltf::Camera& gc = model_.cameras[size_t(index)];
        Camera c;
        c.name = gc.name;
        c.position = glm::vec3(world * glm::dvec4(0, 0, 0, 1));
        // Remove scale from the orientation; keep it right-handed.
        glm::vec3 right = glm::normalize(glm::vec3(world * glm::dvec4(1, 0, 0, 0)));
        glm::vec3 up = glm::vec3(world * glm::dvec4(0, 1, 0, 0));
        up = glm::normalize(up - glm::dot(up, right) * right);
        c.worldFromCamera = glm::mat3(right, up, glm::cross(right, up));
        if (gc.type == "orthographic") {
            c.type = Camera::Type::Orthographic;
            c.xmag = float(gc.orthographic.xmag);
            c.ymag = float(gc.orthographic.ymag);
        } else {
            c.yfov = float(gc.perspective.yfov);
            c.aspectRatio = float(gc.perspective.aspectRatio);
            if (!(c.yfov > 0.0f && c.yfov < 3.14f)) fail("camera " + std::to_string(index) + " has an invalid yfov");
        }
        if (!finite3(c.position) || !finite3(right) || !finite3(up))
            fail("camera " + std::to_string(index) + " has a degenerate transform");
        scene_.cameras.push_back(c);
    }

    // ----- accessors -----

    const tinygltf::Accessor& accessor(int index, const std::string& where) const {
        if (index < 0 || size_t(index) >= model_.accessors.size())
            fail(where + " refers to accessor " + std::to_string(index) + ", which does not exist");
        return model_.accessors[size_t(index)];
    }

    // A normalized integer as glTF defines it (KHR_mesh_quantization): signed ones clamped at -1.
    static double normalizedValue(int componentType, double v) {
        switch (componentType) {
            case TINYGLTF_COMPONENT_TYPE_BYTE: return std::max(v / 127.0, -1.0);
            case TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE: return v / 255.0;
            case TINYGLTF_COMPONENT_TYPE_SHORT: return std::max(v / 32767.0, -1.0);
            case TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT: return v / 65535.0;
            default: return v;
        }
    }

    // ----- KHR_draco_mesh_compression -----
    // Decoded here rather than by tinygltf, whose Draco path indexes buffers, views and attributes from the file
    // unchecked (a Draco primitive with no buffer was a null reference; an attribute id the stream lacks, a null
    // pointer; more than four components, a stack overflow).

    static const tinygltf::Value* dracoExtension(const tinygltf::Primitive& prim) {
        auto it = prim.extensions.find("KHR_draco_mesh_compression");
        return it == prim.extensions.end() ? nullptr : &it->second;
    }

    const draco::Mesh& dracoMesh(const tinygltf::Value& ext, const std::string& where) {
        const tinygltf::Value& bv = ext.Get("bufferView");
        const int viewIndex = bv.IsNumber() ? toInt(bv.GetNumberAsDouble(), -1) : -1;
        if (viewIndex < 0 || size_t(viewIndex) >= model_.bufferViews.size())
            fail(where + ": KHR_draco_mesh_compression refers to a bufferView that does not exist");
        auto cached = dracoMeshes_.find(viewIndex);
        if (cached != dracoMeshes_.end()) return *cached->second;
        const tinygltf::BufferView& view = model_.bufferViews[size_t(viewIndex)];
        if (view.buffer < 0 || size_t(view.buffer) >= model_.buffers.size())
            fail(where + ": KHR_draco_mesh_compression's bufferView " + std::to_string(viewIndex) + " refers to a missing buffer");
        const std::vector<unsigned char>& data = model_.buffers[size_t(view.buffer)].data;
        if (view.byteOffset > data.size() || view.byteLength > data.size() - view.byteOffset)
            fail(where + ": KHR_draco_mesh_compression's bufferView " + std::to_string(viewIndex) + " lies outside its buffer");
        draco::DecoderBuffer buffer;
        buffer.Init(reinterpret_cast<const char*>(data.data() + view.byteOffset), view.byteLength);
        draco::Decoder decoder;
        auto decoded = decoder.DecodeMeshFromBuffer(&buffer);
        if (!decoded.ok()) fail(where + ": its Draco data cannot be decoded (" + decoded.status().error_msg_string() + ")");
        std::unique_ptr<draco::Mesh> mesh = std::move(decoded).value();
        if (!mesh) fail(where + ": its Draco data holds no mesh");
        return *(dracoMeshes_[viewIndex] = std::move(mesh));
    }

    // A vertex attribute, `components` per element: from the Draco stream when the primitive's extension names
    // it, else from its accessor.
    std::vector<double> readAttribute(const tinygltf::Primitive& prim, const std::string& attribute, int components,
                                      const std::string& where) {
        const int index = prim.attributes.at(attribute);
        const tinygltf::Value* ext = dracoExtension(prim);
        if (!ext || !ext->Get("attributes").IsObject() || !ext->Get("attributes").Has(attribute))
            return readAccessor(index, components, where + " " + attribute);
        const std::string name = where + " " + attribute + " (Draco)";
        const tinygltf::Accessor& acc = accessor(index, name);
        if (tinygltf::GetNumComponentsInType(uint32_t(acc.type)) != components)
            fail(name + ": accessor " + std::to_string(index) + " has " + std::to_string(tinygltf::GetNumComponentsInType(uint32_t(acc.type))) +
                 " components per element, expected " + std::to_string(components));
        const tinygltf::Value& id = ext->Get("attributes").Get(attribute);
        const draco::Mesh& mesh = dracoMesh(*ext, where);
        const draco::PointAttribute* a =
            id.IsNumber() && id.GetNumberAsDouble() >= 0.0 && id.GetNumberAsDouble() <= 4294967295.0
                ? mesh.GetAttributeByUniqueId(uint32_t(id.GetNumberAsDouble()))
                : nullptr;
        if (!a) fail(name + ": the Draco stream has no attribute of that id");
        if (a->num_components() != components)
            fail(name + ": the Draco attribute has " + std::to_string(int(a->num_components())) + " components, expected " +
                 std::to_string(components));
        std::vector<double> out(size_t(mesh.num_points()) * size_t(components));
        double value[4];
        for (draco::PointIndex i(0); i < mesh.num_points(); ++i) {
            if (!a->ConvertValue<double>(a->mapped_index(i), int8_t(components), value))
                fail(name + ": a Draco value cannot be read");
            for (int k = 0; k < components; ++k)
                out[size_t(i.value()) * size_t(components) + size_t(k)] =
                    acc.normalized ? normalizedValue(acc.componentType, value[k]) : value[k];
        }
        return out;
    }

    // The primitive's vertex indices, from the Draco stream's faces or the indices accessor (nothing checked
    // against the vertex count here).
    std::vector<double> readIndices(const tinygltf::Primitive& prim, const std::string& where) {
        const tinygltf::Value* ext = dracoExtension(prim);
        if (!ext) return readAccessor(prim.indices, 1, where + " indices");
        const draco::Mesh& mesh = dracoMesh(*ext, where);
        std::vector<double> out;
        out.reserve(size_t(mesh.num_faces()) * 3);
        for (draco::FaceIndex f(0); f < mesh.num_faces(); ++f)
            for (int k = 0; k < 3; ++k) out.push_back(double(mesh.face(f)[k].value()));
        return out;
    }

    // Reads an accessor into doubles, `components` per element, checking every byte range.
    std::vector<double> readAccessor(int index, int components, const std::string& where) const {
        const tinygltf::Accessor& acc = accessor(index, where);
        const std::string name = where + " accessor " + std::to_string(index);
        if (acc.sparse.isSparse) fail(name + " is sparse; sparse accessors are not supported");
        int n = tinygltf::GetNumComponentsInType(uint32_t(acc.type));
        if (n != components)
            fail(name + " has " + std::to_string(n) + " components per element, expected " + std::to_string(components));
        int csize = tinygltf::GetComponentSizeInBytes(uint32_t(acc.componentType));
        if (csize <= 0) fail(name + " has an invalid component type");
        if (acc.bufferView < 0 || size_t(acc.bufferView) >= model_.bufferViews.size())
            fail(name + " has no valid bufferView");
        const tinygltf::BufferView& view = model_.bufferViews[size_t(acc.bufferView)];
        if (view.buffer < 0 || size_t(view.buffer) >= model_.buffers.size())
            fail(name + ": bufferView " + std::to_string(acc.bufferView) + " refers to a missing buffer");
        const std::vector<unsigned char>& data = model_.buffers[size_t(view.buffer)].data;
        // Every size below comes from the file: each sum and product is checked, so a count of 3^-1 mod 2^64 or
        // an offset of 2^64 - 8 cannot wrap into a range that passes.
        const size_t elemSize = size_t(csize) * size_t(n);
        const size_t stride = view.byteStride ? view.byteStride : elemSize;
        if (stride < elemSize) fail(name + ": byteStride smaller than the element size");
        if (view.byteOffset > data.size() || view.byteLength > data.size() - view.byteOffset)
            fail(name + ": bufferView " + std::to_string(acc.bufferView) + " (offset " + std::to_string(view.byteOffset) +
                 ", length " + std::to_string(view.byteLength) + ") lies outside its buffer of " +
                 std::to_string(data.size()) + " bytes");
        if (acc.count > 0) {
            size_t span = 0;  // stride * (count - 1) + elemSize: the bytes the accessor reads
            if (__builtin_mul_overflow(stride, acc.count - 1, &span) || __builtin_add_overflow(span, elemSize, &span) ||
                acc.byteOffset > view.byteLength || span > view.byteLength - acc.byteOffset)
                fail(name + " reads past the end of its buffer (count " + std::to_string(acc.count) + ", byteOffset " +
                     std::to_string(acc.byteOffset) + ", stride " + std::to_string(stride) + "; the bufferView has " +
                     std::to_string(view.byteLength) + " bytes)");
        }
        const size_t begin = view.byteOffset + acc.byteOffset;  // within data: checked above
        std::vector<double> out(acc.count * size_t(n));
        for (size_t i = 0; i < acc.count; ++i) {
            const unsigned char* e = data.data() + begin + i * stride;
            for (int k = 0; k < n; ++k) {
                const unsigned char* p = e + size_t(k) * size_t(csize);
                double v = 0.0;
                switch (acc.componentType) {
                    case TINYGLTF_COMPONENT_TYPE_FLOAT: { float f; std::memcpy(&f, p, 4); v = f; break; }
                    case TINYGLTF_COMPONENT_TYPE_DOUBLE: { double d; std::memcpy(&d, p, 8); v = d; break; }
                    case TINYGLTF_COMPONENT_TYPE_BYTE: { int8_t x; std::memcpy(&x, p, 1); v = x; break; }
                    case TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE: { uint8_t x = *p; v = x; break; }
                    case TINYGLTF_COMPONENT_TYPE_SHORT: { int16_t x; std::memcpy(&x, p, 2); v = x; break; }
                    case TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT: { uint16_t x; std::memcpy(&x, p, 2); v = x; break; }
                    case TINYGLTF_COMPONENT_TYPE_INT: { int32_t x; std::memcpy(&x, p, 4); v = x; break; }
                    case TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT: { uint32_t x; std::memcpy(&x, p, 4); v = x; break; }
                    default: fail(name + " has an unsupported component type");
                }
                out[i * size_t(n) + size_t(k)] = acc.normalized ? normalizedValue(acc.componentType, v) : v;
            }
        }
        return out;
    }

    // ----- meshes -----

    void importMeshInstance(int meshIndex, const glm::dmat4& world) {
        if (size_t(meshIndex) >= model_.meshes.size()) fail("node refers to mesh " + std::to_string(meshIndex) + ", which does not exist");
        ++scene_.stats.meshInstances;
        const tinygltf::Mesh& mesh = model_.meshes[size_t(meshIndex)];
        for (size_t p = 0; p < mesh.primitives.size(); ++p)
            importPrimitive(mesh.primitives[p], world,
                            "mesh " + std::to_string(meshIndex) + (mesh.name.empty() ? std::string() : " (" + mesh.name + ")") + " primitive " + std::to_string(p));
    }

    // The accessor index of a primitive's attribute, -1 if it has none.
    static int attributeIndex(const tinygltf::Primitive& prim, const char* name) {
        auto it = prim.attributes.find(name);
        return it == prim.attributes.end() ? -1 : it->second;
    }

    // A primitive's vertex attributes as read (doubles, in their accessors' layouts), each checked against the
    // POSITION count; empty where the primitive has none.
    struct PrimitiveVertices {
        size_t count = 0;
        std::vector<double> pos, nrm, uv0, uv1, col, tan;
        int colComponents = 0;  // 3 or 4 with COLOR_0
    };

    // POSITION, NORMAL, TEXCOORD_0/1 and COLOR_0 (TANGENT waits for the material: only normal maps use it).
    PrimitiveVertices readVertices(const tinygltf::Primitive& prim, const std::string& where) {
        PrimitiveVertices v;
        v.pos = readAttribute(prim, "POSITION", 3, where);
        v.count = v.pos.size() / 3;
        if (attributeIndex(prim, "NORMAL") >= 0) {
            v.nrm = readAttribute(prim, "NORMAL", 3, where);
            if (v.nrm.size() != v.pos.size()) fail(where + ": NORMAL and POSITION counts differ");
        }
        if (attributeIndex(prim, "TEXCOORD_0") >= 0) {
            v.uv0 = readAttribute(prim, "TEXCOORD_0", 2, where);
            if (v.uv0.size() / 2 != v.count) fail(where + ": TEXCOORD_0 and POSITION counts differ");
        }
        if (attributeIndex(prim, "TEXCOORD_1") >= 0) {
            v.uv1 = readAttribute(prim, "TEXCOORD_1", 2, where);
            if (v.uv1.size() / 2 != v.count) fail(where + ": TEXCOORD_1 and POSITION counts differ");
        }
        if (attributeIndex(prim, "COLOR_0") >= 0) {
            v.colComponents = tinygltf::GetNumComponentsInType(uint32_t(accessor(attributeIndex(prim, "COLOR_0"), where + " COLOR_0").type));
            if (v.colComponents != 3 && v.colComponents != 4) fail(where + ": COLOR_0 must be VEC3 or VEC4");
            v.col = readAttribute(prim, "COLOR_0", v.colComponents, where);
            if (v.col.size() / size_t(v.colComponents) != v.count) fail(where + ": COLOR_0 and POSITION counts differ");
            for (double c : v.col)
                if (!std::isfinite(c)) fail(where + ": COLOR_0 has a non-finite value");
        }
        return v;
    }

    // Vertex indices of the primitive's triangles: its indices (or Draco faces), each checked against the
    // vertex count, or 0, 1, 2, ... without.
    std::vector<uint32_t> readVertexIndices(const tinygltf::Primitive& prim, size_t vertexCount, const std::string& where) {
        std::vector<uint32_t> idx;
        if (prim.indices < 0 && !dracoExtension(prim)) {
            idx.resize(vertexCount);
            for (size_t i = 0; i < vertexCount; ++i) idx[i] = uint32_t(i);
            return idx;
        }
        if (prim.indices >= 0) {
            const tinygltf::Accessor& ia = accessor(prim.indices, where + " indices");
            if (ia.componentType != TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE && ia.componentType != TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT &&
                ia.componentType != TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT)
                fail(where + ": indices must be unsigned byte, short or int");
        }
        std::vector<double> raw = readIndices(prim, where);
        idx.reserve(raw.size());
        for (size_t i = 0; i < raw.size(); ++i) {
            if (raw[i] >= double(vertexCount))
                fail(where + ": index " + std::to_string(uint64_t(raw[i])) + " at position " + std::to_string(i) +
                     " is out of range (the primitive has " + std::to_string(vertexCount) + " vertices)");
            idx.push_back(uint32_t(raw[i]));
        }
        return idx;
    }

    // The triangles of a list, a strip or a fan (in the file's winding).
    std::vector<glm::uvec3> assembleTriangles(int mode, const std::vector<uint32_t>& idx, const std::string& where) {
        std::vector<glm::uvec3> tris;
        if (mode == TINYGLTF_MODE_TRIANGLES) {
            if (idx.size() % 3 != 0) warn(where + ": index count is not a multiple of 3; the remainder is ignored");
            for (size_t i = 0; i + 2 < idx.size(); i += 3) tris.emplace_back(idx[i], idx[i + 1], idx[i + 2]);
        } else if (mode == TINYGLTF_MODE_TRIANGLE_STRIP) {
            for (size_t i = 0; i + 2 < idx.size(); ++i)
                tris.push_back(i % 2 == 0 ? glm::uvec3(idx[i], idx[i + 1], idx[i + 2]) : glm::uvec3(idx[i + 1], idx[i], idx[i + 2]));
        } else {
            for (size_t i = 1; i + 1 < idx.size(); ++i) tris.emplace_back(idx[i], idx[i + 1], idx[0]);
        }
        return tris;
    }

    // The flattened scene's size, bounded before anything is emitted (the vertex indices are 32-bit).
    void checkSceneSize(const PrimitiveVertices& pv, size_t triangles, const std::string& where) {
        scene_.stats.trianglesRead += triangles;
        const uint64_t maxVertices = std::min<uint64_t>(3 * limits_.maxTriangles, std::numeric_limits<uint32_t>::max());
        const uint64_t vertices = uint64_t(scene_.mesh.positions.size()) + (pv.nrm.empty() ? 3 * uint64_t(triangles) : pv.count);
        if (scene_.stats.trianglesRead > limits_.maxTriangles || vertices > maxVertices)
            fail(where + ": the flattened scene exceeds " + std::to_string(limits_.maxTriangles) + " triangles (" +
                 std::to_string(scene_.stats.trianglesRead) + " so far, " + std::to_string(scene_.stats.meshInstances) +
                 " mesh instances) or " + std::to_string(maxVertices) + " vertices (" + std::to_string(vertices) +
                 "); raise --max-triangles if the machine has the memory");
    }

    // A primitive's vertices in world space: positions (in double, then float), unit normals (zero where
    // degenerate or absent) and, for normal maps, tangent frames (xyz, w the bitangent sign).
    struct WorldVertices {
        std::vector<glm::vec3> p, n;
        std::vector<glm::vec4> t;
        bool flipWinding = false;  // the transform mirrors: triangles are emitted with their winding reversed
    };

    WorldVertices toWorld(const PrimitiveVertices& pv, const glm::dmat4& world, const std::string& where) {
        WorldVertices w;
        glm::dmat3 normalFromObject = glm::transpose(glm::inverse(glm::dmat3(world)));
        w.flipWinding = glm::determinant(glm::dmat3(world)) < 0.0;
        w.p.resize(pv.count);
        w.n.assign(pv.count, glm::vec3(0.0f));
        for (size_t v = 0; v < pv.count; ++v) {
            glm::dvec3 p(pv.pos[3 * v], pv.pos[3 * v + 1], pv.pos[3 * v + 2]);
            if (!std::isfinite(p.x) || !std::isfinite(p.y) || !std::isfinite(p.z))
                fail(where + ": vertex " + std::to_string(v) + " has a non-finite position");
            w.p[v] = glm::vec3(world * glm::dvec4(p, 1.0));
            if (!finite3(w.p[v])) fail(where + ": vertex " + std::to_string(v) + " is not finite in world space");
            if (!pv.nrm.empty()) {
                glm::dvec3 n = normalFromObject * glm::dvec3(pv.nrm[3 * v], pv.nrm[3 * v + 1], pv.nrm[3 * v + 2]);
                double len = glm::length(n);
                w.n[v] = (std::isfinite(len) && len > 0.0) ? glm::vec3(n / len) : glm::vec3(0.0f);
            }
        }
        return w;
    }

    // Tangents generated from the normal texture's coordinates: dp/du and dp/dv of a triangle, and the frame
    // they give a normal (+Y of the map towards -v, as glTF defines it).
    struct GeneratedTangents {
        const std::vector<glm::vec3>& wp;
        const std::vector<double>& tuv;  // the normal texture's coordinates (empty: none)
        const TextureRef& texture;
        glm::vec2 uvOf(uint32_t v) const { return tuv.empty() ? glm::vec2(0.0f) : texture.apply(glm::vec2(tuv[2 * v], tuv[2 * v + 1])); }
        // dp/du and dp/dv of triangle t (zero for a degenerate mapping).
        void triangle(const glm::uvec3& t, glm::vec3& dpdu, glm::vec3& dpdv) const {
            glm::vec3 e1 = wp[t.y] - wp[t.x], e2 = wp[t.z] - wp[t.x];
            glm::vec2 d1 = uvOf(t.y) - uvOf(t.x), d2 = uvOf(t.z) - uvOf(t.x);
            float det = d1.x * d2.y - d2.x * d1.y;
            if (!(std::abs(det) > 1e-20f) || !std::isfinite(det)) {
                dpdu = dpdv = glm::vec3(0.0f);
                return;
            }
            float r = 1.0f / det;
            dpdu = (e1 * d2.y - e2 * d1.y) * r;
            dpdv = (e2 * d1.x - e1 * d2.x) * r;
        }
        static glm::vec4 frame(const glm::vec3& n, const glm::vec3& dpdu, const glm::vec3& dpdv) {
            glm::vec3 t = dpdu - glm::dot(n, dpdu) * n;
            float len = glm::length(t);
            if (!(len > 0.0f) || !std::isfinite(len)) return glm::vec4(0, 0, 0, 1);
            t /= len;
            return glm::vec4(t, glm::dot(glm::cross(n, t), -dpdv) < 0.0f ? -1.0f : 1.0f);
        }
    };

    // Tangent frames for normal maps: TANGENT (world space, w flipped with the winding), else, for smooth
    // primitives, generated per vertex (sums of the triangles' dp/du, the bitangent sign from dp/dv); flat
    // ones get theirs per triangle as they are emitted.
    void tangentFrames(const PrimitiveVertices& pv, const glm::dmat4& world, const std::vector<glm::uvec3>& tris,
                       const GeneratedTangents& generated, WorldVertices& w) {
        w.t.assign(pv.count, glm::vec4(0.0f, 0.0f, 0.0f, 1.0f));
        if (!pv.tan.empty()) {
            glm::dmat3 m3(world);
            for (size_t v = 0; v < pv.count; ++v) {
                glm::dvec3 t = m3 * glm::dvec3(pv.tan[4 * v], pv.tan[4 * v + 1], pv.tan[4 * v + 2]);
                double len = glm::length(t);
                double sign = (pv.tan[4 * v + 3] < 0.0 ? -1.0 : 1.0) * (w.flipWinding ? -1.0 : 1.0);
                w.t[v] = std::isfinite(len) && len > 0.0 ? glm::vec4(glm::vec3(t / len), float(sign)) : glm::vec4(0, 0, 0, 1);
            }
            return;
        }
        ++scene_.stats.primitivesWithGeneratedTangents;
        if (pv.nrm.empty()) return;
        std::vector<glm::vec3> su(pv.count, glm::vec3(0.0f)), sv(pv.count, glm::vec3(0.0f));
        for (glm::uvec3 t : tris) {
            if (w.flipWinding) std::swap(t.y, t.z);
            glm::vec3 dpdu, dpdv;
            generated.triangle(t, dpdu, dpdv);
            for (uint32_t v : {t.x, t.y, t.z}) {
                su[v] += dpdu;
                sv[v] += dpdv;
            }
        }
        for (size_t v = 0; v < pv.count; ++v) w.t[v] = GeneratedTangents::frame(w.n[v], su[v], sv[v]);
    }

    // Appends the primitive to the scene's mesh. Vertices are emitted per primitive instance; flat-shaded
    // primitives (no normals) get unshared vertices; degenerate triangles are dropped.
    void emitPrimitive(const PrimitiveVertices& pv, const WorldVertices& w, const std::vector<glm::uvec3>& tris, uint32_t material,
                       bool normalMapped, const GeneratedTangents& generated) {
        TriangleMesh& out = scene_.mesh;
        const bool flat = pv.nrm.empty();
        // Optional attributes present in the mesh (backfilled with defaults when this is the first primitive).
        const bool withColors = !pv.col.empty() || !out.colors.empty(), withTangents = normalMapped || !out.tangents.empty();
        if (withColors) out.colors.resize(out.positions.size(), glm::vec4(1.0f));
        if (withTangents) out.tangents.resize(out.positions.size(), glm::vec4(0, 0, 0, 1));
        uint32_t base = uint32_t(out.positions.size());
        auto pushVertex = [&](uint32_t v, const glm::vec3& normal, const glm::vec4& tangent) {
            out.positions.push_back(w.p[v]);
            out.normals.push_back(normal);
            out.uv0.push_back(pv.uv0.empty() ? glm::vec2(0.0f) : glm::vec2(pv.uv0[2 * v], pv.uv0[2 * v + 1]));
            out.uv1.push_back(pv.uv1.empty() ? glm::vec2(0.0f) : glm::vec2(pv.uv1[2 * v], pv.uv1[2 * v + 1]));
            if (withColors) {
                glm::vec4 c(1.0f);
                if (!pv.col.empty())
                    for (int k = 0; k < pv.colComponents; ++k) c[k] = float(pv.col[size_t(pv.colComponents) * v + size_t(k)]);
                out.colors.push_back(glm::clamp(c, 0.0f, 1.0f));
            }
            if (withTangents) out.tangents.push_back(tangent);
        };
        if (!flat)
            for (size_t v = 0; v < pv.count; ++v) pushVertex(uint32_t(v), w.n[v], normalMapped ? w.t[v] : glm::vec4(0, 0, 0, 1));
        for (glm::uvec3 t : tris) {
            if (w.flipWinding) std::swap(t.y, t.z);
            glm::vec3 e1 = w.p[t.y] - w.p[t.x], e2 = w.p[t.z] - w.p[t.x];
            glm::vec3 c = glm::cross(e1, e2);
            float len = glm::length(c);
            if (!(len > 0.0f) || !std::isfinite(len)) {
                ++scene_.stats.degenerateTrianglesDropped;
                continue;
            }
            if (flat) {
                glm::vec3 n = c / len;
                glm::vec4 tg[3] = {glm::vec4(0, 0, 0, 1), glm::vec4(0, 0, 0, 1), glm::vec4(0, 0, 0, 1)};
                if (normalMapped && pv.tan.empty()) {
                    glm::vec3 dpdu, dpdv;
                    generated.triangle(t, dpdu, dpdv);
                    tg[0] = tg[1] = tg[2] = GeneratedTangents::frame(n, dpdu, dpdv);
                } else if (normalMapped) {
                    tg[0] = w.t[t.x], tg[1] = w.t[t.y], tg[2] = w.t[t.z];
                }
                uint32_t first = uint32_t(out.positions.size());
                pushVertex(t.x, n, tg[0]);
                pushVertex(t.y, n, tg[1]);
                pushVertex(t.z, n, tg[2]);
                out.triangles.emplace_back(first, first + 1, first + 2);
            } else {
                out.triangles.emplace_back(base + t.x, base + t.y, base + t.z);
            }
            out.materialIds.push_back(material);
        }
    }

    void importPrimitive(const tinygltf::Primitive& prim, const glm::dmat4& world, const std::string& where) {
        ++scene_.stats.primitives;
        if (prim.extensions.count("KHR_draco_mesh_compression")) ++scene_.stats.dracoPrimitives;
        if (prim.mode != TINYGLTF_MODE_TRIANGLES && prim.mode != TINYGLTF_MODE_TRIANGLE_STRIP &&
            prim.mode != TINYGLTF_MODE_TRIANGLE_FAN) {
            ++scene_.stats.primitivesSkipped;
            return;  // points and lines have no area: nothing to render
        }
        if (attributeIndex(prim, "POSITION") < 0) {
            warn(where + " has no POSITION attribute; skipped");
            ++scene_.stats.primitivesSkipped;
            return;
        }
        PrimitiveVertices pv = readVertices(prim, where);
        const uint32_t material = uint32_t(materialIndexFor(prim.material));
        const Material& mat = scene_.materials[material];
        const bool normalMapped = mat.normalTexture.valid();
        if (normalMapped && attributeIndex(prim, "TANGENT") >= 0) {
            pv.tan = readAttribute(prim, "TANGENT", 4, where);
            if (pv.tan.size() / 4 != pv.count) fail(where + ": TANGENT and POSITION counts differ");
        }
        const std::vector<glm::uvec3> tris = assembleTriangles(prim.mode, readVertexIndices(prim, pv.count, where), where);
        checkSceneSize(pv, tris.size(), where);
        WorldVertices w = toWorld(pv, world, where);
        if (pv.nrm.empty()) ++scene_.stats.primitivesWithGeneratedNormals;
        const GeneratedTangents generated{w.p, mat.normalTexture.texCoord == 1 ? pv.uv1 : pv.uv0, mat.normalTexture};
        if (normalMapped) tangentFrames(pv, world, tris, generated, w);
        emitPrimitive(pv, w, tris, material, normalMapped, generated);
    }

    std::string path_;
    tinygltf::Model& model_;
    const ImportLimits& limits_;
    Scene& scene_;
    std::map<std::pair<int, bool>, int> textureCache_;
    std::map<int, std::unique_ptr<draco::Mesh>> dracoMeshes_;  // by bufferView
    int defaultMaterial_ = -1;
};

bool hasGlbMagic(const std::vector<uint8_t>& bytes) { return bytes.size() >= 4 && std::memcmp(bytes.data(), "glTF", 4) == 0; }

// What tinygltf's callbacks need: the model it is filling (its buffers and views are parsed before its
// images), the limits, the first limit broken (reported as itself, not as "not a valid glTF file"), and
// whether files outside the input may be read.
struct LoadContext {
    const tinygltf::Model* model = nullptr;
    const ImportLimits* limits = nullptr;
    bool allowExternalFiles = true;
    std::string limitError;
};

// Image decoding with its size checked from the header first, so a small file cannot make the importer
// decode gigabytes. tinygltf hands an image stored in a bufferView over without checking the view against
// its buffer; that is checked here too, before a byte is read.
bool loadImageChecked(tinygltf::Image* image, const int index, std::string* err, std::string* warn, int reqWidth,
                      int reqHeight, const unsigned char* bytes, int size, void* user) {
    LoadContext& ctx = *static_cast<LoadContext*>(user);
    if (image->bufferView >= 0) {
        const tinygltf::BufferView& view = ctx.model->bufferViews[size_t(image->bufferView)];  // tinygltf checked the index
        const size_t bufferSize = ctx.model->buffers[size_t(view.buffer)].data.size();
        if (view.byteOffset > bufferSize || view.byteLength > bufferSize - view.byteOffset ||
            view.byteLength > size_t(std::numeric_limits<int>::max())) {
            *err += "image " + std::to_string(index) + ": its bufferView lies outside its buffer\n";
            return false;
        }
    }
    int width = 0, height = 0, channels = 0;
    if (size > 0 && stbi_info_from_memory(bytes, size, &width, &height, &channels) &&
        uint64_t(width) * uint64_t(height) > ctx.limits->maxTexturePixels) {
        ctx.limitError = "image " + std::to_string(index) + " is " + std::to_string(width) + " x " + std::to_string(height) +
                         " pixels, more than the limit of " + std::to_string(ctx.limits->maxTexturePixels) +
                         " (--max-texture-pixels)";
        *err += ctx.limitError + "\n";
        return false;
    }
    return tinygltf::LoadImageData(image, index, err, warn, reqWidth, reqHeight, bytes, size, nullptr);
}

// Files a glTF names by URI: regular files only (a URI naming /dev/stdin or a FIFO would block the import),
// and none at all where the caller forbids them.
bool regularFile(const std::string& path) {
    struct stat st {};
    return ::stat(path.c_str(), &st) == 0 && S_ISREG(st.st_mode);
}
bool fileExists(const std::string& path, void* user) {
    return static_cast<LoadContext*>(user)->allowExternalFiles && regularFile(path);
}
std::string expandFilePath(const std::string& path, void*) { return path; }
bool readWholeFile(std::vector<unsigned char>* out, std::string* err, const std::string& path, void* user) {
    if (!static_cast<LoadContext*>(user)->allowExternalFiles || !regularFile(path)) {
        *err += path + ": not a readable regular file\n";
        return false;
    }
    return tinygltf::ReadWholeFile(out, err, path, nullptr);
}
bool writeWholeFile(std::string* err, const std::string&, const std::vector<unsigned char>&, void*) {
    *err += "the importer writes no files\n";
    return false;
}

// tinygltf without its Draco path still demands that a primitive's indices accessor have a bufferView, which a
// Draco primitive's has not (its indices are the stream's faces): the `indices` of Draco primitives are taken
// out of the JSON before tinygltf parses it (the importer reads the faces). Returns the bytes to parse: the
// same when nothing needs it, else the document (or .glb) rewritten.
std::vector<uint8_t> withoutDracoIndices(const std::vector<uint8_t>& bytes) {
    const bool glb = hasGlbMagic(bytes);
    size_t jsonBegin = 0, jsonLength = bytes.size();
    if (glb) {
        uint32_t chunkLength = 0, chunkType = 0;
        if (bytes.size() < 20) return bytes;  // tinygltf reports it
        std::memcpy(&chunkLength, bytes.data() + 12, 4);
        std::memcpy(&chunkType, bytes.data() + 16, 4);
        if (chunkType != 0x4E4F534Au || chunkLength > bytes.size() - 20) return bytes;
        jsonBegin = 20;
        jsonLength = chunkLength;
    }
    const char* text = reinterpret_cast<const char*>(bytes.data()) + jsonBegin;
    if (std::string_view(text, jsonLength).find("KHR_draco_mesh_compression") == std::string_view::npos) return bytes;
    nlohmann::json doc = nlohmann::json::parse(text, text + jsonLength, nullptr, false);
    if (doc.is_discarded() || !doc.is_object() || !doc.contains("meshes") || !doc["meshes"].is_array()) return bytes;
    bool changed = false;
    for (nlohmann::json& mesh : doc["meshes"]) {
        if (!mesh.is_object() || !mesh.contains("primitives") || !mesh["primitives"].is_array()) continue;
        for (nlohmann::json& prim : mesh["primitives"])
            if (prim.is_object() && prim.contains("indices") && prim.contains("extensions") && prim["extensions"].is_object() &&
                prim["extensions"].contains("KHR_draco_mesh_compression")) {
                prim.erase("indices");
                changed = true;
            }
    }
    if (!changed) return bytes;
    std::string json = doc.dump();
    if (!glb) return std::vector<uint8_t>(json.begin(), json.end());
    json.append((4 - json.size() % 4) % 4, ' ');
    const size_t rest = jsonBegin + jsonLength;  // the chunks after JSON, as they are
    std::vector<uint8_t> out(12);
    std::memcpy(out.data(), bytes.data(), 8);
    const uint32_t newJsonLength = uint32_t(json.size()), jsonType = 0x4E4F534Au;
    out.insert(out.end(), reinterpret_cast<const uint8_t*>(&newJsonLength), reinterpret_cast<const uint8_t*>(&newJsonLength) + 4);
    out.insert(out.end(), reinterpret_cast<const uint8_t*>(&jsonType), reinterpret_cast<const uint8_t*>(&jsonType) + 4);
    out.insert(out.end(), json.begin(), json.end());
    out.insert(out.end(), bytes.begin() + std::ptrdiff_t(rest), bytes.end());
    const uint32_t total = uint32_t(std::min<size_t>(out.size(), std::numeric_limits<uint32_t>::max()));
    std::memcpy(out.data() + 8, &total, 4);
    return out;
}

}  // namespace

Scene loadGltf(const std::string& path, const ImportLimits& limits) {
    std::ifstream f(path, std::ios::binary);
    if (!f || !regularFile(path)) throw SceneError(path + ": cannot open file");
    std::vector<uint8_t> bytes((std::istreambuf_iterator<char>(f)), std::istreambuf_iterator<char>());
    if (f.bad()) throw SceneError(path + ": cannot read file");
    return loadGltfFromMemory(bytes, path, limits);
}

Scene loadGltfFromMemory(const std::vector<uint8_t>& bytes, const std::string& path, const ImportLimits& limits,
                         bool allowExternalFiles) {
    tinygltf::Model model;
    LoadContext ctx;
    ctx.model = &model;
    ctx.limits = &limits;
    ctx.allowExternalFiles = allowExternalFiles;
    tinygltf::TinyGLTF loader;
    loader.SetImageLoader(loadImageChecked, &ctx);
    loader.SetFsCallbacks(tinygltf::FsCallbacks{fileExists, expandFilePath, readWholeFile, writeWholeFile, &ctx});
    const std::string baseDir = path.find('/') == std::string::npos ? std::string(".") : path.substr(0, path.rfind('/'));
    std::string err, warn;
    bool ok = false;
    // tinygltf takes the size as a 32-bit unsigned
    if (bytes.size() > std::numeric_limits<uint32_t>::max())
        throw SceneError(path + ": the file is larger than 4 GiB, which glTF does not allow");
    const std::vector<uint8_t> parsed = withoutDracoIndices(bytes);
    if (parsed.size() > std::numeric_limits<uint32_t>::max())
        throw SceneError(path + ": the file is larger than 4 GiB, which glTF does not allow");
    if (hasGlbMagic(parsed))
        ok = loader.LoadBinaryFromMemory(&model, &err, &warn, parsed.data(), unsigned(parsed.size()), baseDir);
    else
        ok = loader.LoadASCIIFromString(&model, &err, &warn, reinterpret_cast<const char*>(parsed.data()),
                                        unsigned(parsed.size()), baseDir);
    if (!ctx.limitError.empty()) throw SceneError(path + ": " + ctx.limitError);
    if (!ok) throw SceneError(path + ": not a valid glTF file: " + trim(err.empty() ? warn : err));

    Scene scene;
    scene.sourcePath = path;
    if (!warn.empty()) scene.stats.warnings.push_back(trim(warn));
    Importer(path, model, limits, scene).run();
    return scene;
}

}  // namespace nrad
