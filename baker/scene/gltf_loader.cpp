// glTF 2.0 import through tinygltf (with Draco). Validates every index and byte range it reads, so a
// malformed file becomes a SceneError naming the file, never undefined behaviour.
#include "baker/scene/gltf_loader.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstring>
#include <fstream>
#include <map>
#include <set>
#include <sstream>

#include <glm/gtc/matrix_transform.hpp>
#include <glm/gtc/quaternion.hpp>
#include <glm/gtc/type_ptr.hpp>
#include <nlohmann/json.hpp>
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

std::string trim(std::string s) {
    while (!s.empty() && (s.back() == '\n' || s.back() == ' ' || s.back() == '\r')) s.pop_back();
    return s;
}

class Importer {
public:
    Importer(const std::string& path, tinygltf::Model& model, Scene& scene)
        : path_(path), model_(model), scene_(scene) {}

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
            int tc = int(number(t, "texCoord", 0.0));
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
            size_t need = size_t(img.width) * size_t(img.height) * size_t(comp) * size_t(bytes);
            if (comp < 1 || comp > 4 || (bytes != 1 && bytes != 2) || img.image.size() < need)
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
                    int index = int(number(t, "index", -1.0)), texCoord = int(number(t, "texCoord", 0.0));
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
            addLightInstance(lp->second.Get("light").GetNumberAsInt(), world);
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
            fail(name + " has no valid bufferView" + (scene_.stats.dracoPrimitives ? " (Draco decoding failed?)" : ""));
        const tinygltf::BufferView& view = model_.bufferViews[size_t(acc.bufferView)];
        if (view.buffer < 0 || size_t(view.buffer) >= model_.buffers.size())
            fail(name + ": bufferView " + std::to_string(acc.bufferView) + " refers to a missing buffer");
        const std::vector<unsigned char>& data = model_.buffers[size_t(view.buffer)].data;
        size_t elemSize = size_t(csize) * size_t(n);
        size_t stride = view.byteStride ? view.byteStride : elemSize;
        if (stride < elemSize) fail(name + ": byteStride smaller than the element size");
        size_t begin = view.byteOffset + acc.byteOffset;
        if (acc.count > 0) {
            size_t lastEnd = begin + stride * (acc.count - 1) + elemSize;
            if (view.byteOffset > data.size() || view.byteLength > data.size() - view.byteOffset ||
                acc.byteOffset + stride * (acc.count - 1) + elemSize > view.byteLength || lastEnd > data.size())
                fail(name + " reads past the end of its buffer (count " + std::to_string(acc.count) +
                     ", buffer has " + std::to_string(data.size()) + " bytes)");
        }
        std::vector<double> out(acc.count * size_t(n));
        for (size_t i = 0; i < acc.count; ++i) {
            const unsigned char* e = data.data() + begin + i * stride;
            for (int k = 0; k < n; ++k) {
                const unsigned char* p = e + size_t(k) * size_t(csize);
                double v = 0.0;
                switch (acc.componentType) {
                    case TINYGLTF_COMPONENT_TYPE_FLOAT: { float f; std::memcpy(&f, p, 4); v = f; break; }
                    case TINYGLTF_COMPONENT_TYPE_DOUBLE: { double d; std::memcpy(&d, p, 8); v = d; break; }
                    case TINYGLTF_COMPONENT_TYPE_BYTE: { int8_t x; std::memcpy(&x, p, 1); v = acc.normalized ? std::max(x / 127.0, -1.0) : x; break; }
                    case TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE: { uint8_t x = *p; v = acc.normalized ? x / 255.0 : x; break; }
                    case TINYGLTF_COMPONENT_TYPE_SHORT: { int16_t x; std::memcpy(&x, p, 2); v = acc.normalized ? std::max(x / 32767.0, -1.0) : x; break; }
                    case TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT: { uint16_t x; std::memcpy(&x, p, 2); v = acc.normalized ? x / 65535.0 : x; break; }
                    case TINYGLTF_COMPONENT_TYPE_INT: { int32_t x; std::memcpy(&x, p, 4); v = x; break; }
                    case TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT: { uint32_t x; std::memcpy(&x, p, 4); v = x; break; }
                    default: fail(name + " has an unsupported component type");
                }
                out[i * size_t(n) + size_t(k)] = v;
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

    void importPrimitive(const tinygltf::Primitive& prim, const glm::dmat4& world, const std::string& where) {
        ++scene_.stats.primitives;
        if (prim.extensions.count("KHR_draco_mesh_compression")) ++scene_.stats.dracoPrimitives;
        if (prim.mode != TINYGLTF_MODE_TRIANGLES && prim.mode != TINYGLTF_MODE_TRIANGLE_STRIP &&
            prim.mode != TINYGLTF_MODE_TRIANGLE_FAN) {
            ++scene_.stats.primitivesSkipped;
            return;  // points and lines have no area: nothing to render
        }
        auto attr = [&](const char* name) {
            auto it = prim.attributes.find(name);
            return it == prim.attributes.end() ? -1 : it->second;
        };
        int posIndex = attr("POSITION");
        if (posIndex < 0) {
            warn(where + " has no POSITION attribute; skipped");
            ++scene_.stats.primitivesSkipped;
            return;
        }
        std::vector<double> pos = readAccessor(posIndex, 3, where + " POSITION");
        size_t vertexCount = pos.size() / 3;
        std::vector<double> nrm, uv0, uv1;
        if (attr("NORMAL") >= 0) {
            nrm = readAccessor(attr("NORMAL"), 3, where + " NORMAL");
            if (nrm.size() != pos.size()) fail(where + ": NORMAL and POSITION counts differ");
        }
        if (attr("TEXCOORD_0") >= 0) {
            uv0 = readAccessor(attr("TEXCOORD_0"), 2, where + " TEXCOORD_0");
            if (uv0.size() / 2 != vertexCount) fail(where + ": TEXCOORD_0 and POSITION counts differ");
        }
        if (attr("TEXCOORD_1") >= 0) {
            uv1 = readAccessor(attr("TEXCOORD_1"), 2, where + " TEXCOORD_1");
            if (uv1.size() / 2 != vertexCount) fail(where + ": TEXCOORD_1 and POSITION counts differ");
        }

        std::vector<double> col, tan;
        int colComponents = 0;
        if (attr("COLOR_0") >= 0) {
            colComponents = tinygltf::GetNumComponentsInType(uint32_t(accessor(attr("COLOR_0"), where + " COLOR_0").type));
            if (colComponents != 3 && colComponents != 4) fail(where + ": COLOR_0 must be VEC3 or VEC4");
            col = readAccessor(attr("COLOR_0"), colComponents, where + " COLOR_0");
            if (col.size() / size_t(colComponents) != vertexCount) fail(where + ": COLOR_0 and POSITION counts differ");
            for (double c : col)
                if (!std::isfinite(c)) fail(where + ": COLOR_0 has a non-finite value");
        }
        const uint32_t material = uint32_t(materialIndexFor(prim.material));
        const Material& mat = scene_.materials[material];
        const bool normalMapped = mat.normalTexture.valid();
        if (normalMapped && attr("TANGENT") >= 0) {
            tan = readAccessor(attr("TANGENT"), 4, where + " TANGENT");
            if (tan.size() / 4 != vertexCount) fail(where + ": TANGENT and POSITION counts differ");
        }

        // Vertex indices of the primitive's triangles.
        std::vector<uint32_t> idx;
        if (prim.indices >= 0) {
            const tinygltf::Accessor& ia = accessor(prim.indices, where + " indices");
            if (ia.componentType != TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE &&
                ia.componentType != TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT &&
                ia.componentType != TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT)
                fail(where + ": indices must be unsigned byte, short or int");
            std::vector<double> raw = readAccessor(prim.indices, 1, where + " indices");
            idx.reserve(raw.size());
            for (size_t i = 0; i < raw.size(); ++i) {
                if (raw[i] >= double(vertexCount))
                    fail(where + ": index " + std::to_string(uint64_t(raw[i])) + " at position " + std::to_string(i) +
                         " is out of range (the primitive has " + std::to_string(vertexCount) + " vertices)");
                idx.push_back(uint32_t(raw[i]));
            }
        } else {
            idx.resize(vertexCount);
            for (size_t i = 0; i < vertexCount; ++i) idx[i] = uint32_t(i);
        }
        std::vector<glm::uvec3> tris;
        if (prim.mode == TINYGLTF_MODE_TRIANGLES) {
            if (idx.size() % 3 != 0) warn(where + ": index count is not a multiple of 3; the remainder is ignored");
            for (size_t i = 0; i + 2 < idx.size(); i += 3) tris.emplace_back(idx[i], idx[i + 1], idx[i + 2]);
        } else if (prim.mode == TINYGLTF_MODE_TRIANGLE_STRIP) {
            for (size_t i = 0; i + 2 < idx.size(); ++i)
                tris.push_back(i % 2 == 0 ? glm::uvec3(idx[i], idx[i + 1], idx[i + 2]) : glm::uvec3(idx[i + 1], idx[i], idx[i + 2]));
        } else {
            for (size_t i = 1; i + 1 < idx.size(); ++i) tris.emplace_back(idx[i], idx[i + 1], idx[0]);
        }
        scene_.stats.trianglesRead += tris.size();

        // Transform to world space (positions in double, then float).
        glm::dmat3 normalFromObject = glm::transpose(glm::inverse(glm::dmat3(world)));
        bool flipWinding = glm::determinant(glm::dmat3(world)) < 0.0;
        std::vector<glm::vec3> wp(vertexCount), wn(vertexCount, glm::vec3(0.0f));
        for (size_t v = 0; v < vertexCount; ++v) {
            glm::dvec3 p(pos[3 * v], pos[3 * v + 1], pos[3 * v + 2]);
            if (!std::isfinite(p.x) || !std::isfinite(p.y) || !std::isfinite(p.z))
                fail(where + ": vertex " + std::to_string(v) + " has a non-finite position");
            wp[v] = glm::vec3(world * glm::dvec4(p, 1.0));
            if (!finite3(wp[v])) fail(where + ": vertex " + std::to_string(v) + " is not finite in world space");
            if (!nrm.empty()) {
                glm::dvec3 n = normalFromObject * glm::dvec3(nrm[3 * v], nrm[3 * v + 1], nrm[3 * v + 2]);
                double len = glm::length(n);
                wn[v] = (std::isfinite(len) && len > 0.0) ? glm::vec3(n / len) : glm::vec3(0.0f);
            }
        }

        TriangleMesh& out = scene_.mesh;
        bool flat = nrm.empty();
        if (flat) ++scene_.stats.primitivesWithGeneratedNormals;

        // Tangent frames for normal maps: TANGENT (world space, w flipped with the winding), else generated from
        // the normal texture's coordinates (per-vertex sums of the triangles' dp/du, the bitangent sign from
        // dp/dv; +Y of the map towards -v, as glTF defines it).
        std::vector<glm::vec4> wt;
        if (normalMapped) {
            wt.assign(vertexCount, glm::vec4(0.0f, 0.0f, 0.0f, 1.0f));
            if (!tan.empty()) {
                glm::dmat3 m3(world);
                for (size_t v = 0; v < vertexCount; ++v) {
                    glm::dvec3 t = m3 * glm::dvec3(tan[4 * v], tan[4 * v + 1], tan[4 * v + 2]);
                    double len = glm::length(t);
                    double w = (tan[4 * v + 3] < 0.0 ? -1.0 : 1.0) * (flipWinding ? -1.0 : 1.0);
                    wt[v] = std::isfinite(len) && len > 0.0 ? glm::vec4(glm::vec3(t / len), float(w)) : glm::vec4(0, 0, 0, 1);
                }
            } else {
                ++scene_.stats.primitivesWithGeneratedTangents;
            }
        }
        const std::vector<double>& tuv = mat.normalTexture.texCoord == 1 ? uv1 : uv0;
        auto uvOf = [&](uint32_t v) {
            return tuv.empty() ? glm::vec2(0.0f) : mat.normalTexture.apply(glm::vec2(tuv[2 * v], tuv[2 * v + 1]));
        };
        // dp/du and dp/dv of triangle t (zero for a degenerate mapping).
        auto triangleTangents = [&](const glm::uvec3& t, glm::vec3& dpdu, glm::vec3& dpdv) {
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
        };
        auto frame = [](const glm::vec3& n, const glm::vec3& dpdu, const glm::vec3& dpdv) {
            glm::vec3 t = dpdu - glm::dot(n, dpdu) * n;
            float len = glm::length(t);
            if (!(len > 0.0f) || !std::isfinite(len)) return glm::vec4(0, 0, 0, 1);
            t /= len;
            return glm::vec4(t, glm::dot(glm::cross(n, t), -dpdv) < 0.0f ? -1.0f : 1.0f);
        };
        if (normalMapped && tan.empty() && !flat) {
            std::vector<glm::vec3> su(vertexCount, glm::vec3(0.0f)), sv(vertexCount, glm::vec3(0.0f));
            for (glm::uvec3 t : tris) {
                if (flipWinding) std::swap(t.y, t.z);
                glm::vec3 dpdu, dpdv;
                triangleTangents(t, dpdu, dpdv);
                for (uint32_t v : {t.x, t.y, t.z}) {
                    su[v] += dpdu;
                    sv[v] += dpdv;
                }
            }
            for (size_t v = 0; v < vertexCount; ++v) wt[v] = frame(wn[v], su[v], sv[v]);
        }
        // Optional attributes present in the mesh (backfilled with defaults when this is the first primitive).
        const bool withColors = !col.empty() || !out.colors.empty(), withTangents = normalMapped || !out.tangents.empty();
        if (withColors) out.colors.resize(out.positions.size(), glm::vec4(1.0f));
        if (withTangents) out.tangents.resize(out.positions.size(), glm::vec4(0, 0, 0, 1));
        // Vertices are emitted per primitive instance; flat-shaded primitives get unshared vertices.
        uint32_t base = uint32_t(out.positions.size());
        auto pushVertex = [&](uint32_t v, const glm::vec3& normal, const glm::vec4& tangent) {
            out.positions.push_back(wp[v]);
            out.normals.push_back(normal);
            out.uv0.push_back(uv0.empty() ? glm::vec2(0.0f) : glm::vec2(uv0[2 * v], uv0[2 * v + 1]));
            out.uv1.push_back(uv1.empty() ? glm::vec2(0.0f) : glm::vec2(uv1[2 * v], uv1[2 * v + 1]));
            if (withColors) {
                glm::vec4 c(1.0f);
                if (!col.empty())
                    for (int k = 0; k < colComponents; ++k) c[k] = float(col[size_t(colComponents) * v + size_t(k)]);
                out.colors.push_back(glm::clamp(c, 0.0f, 1.0f));
            }
            if (withTangents) out.tangents.push_back(tangent);
        };
        if (!flat)
            for (size_t v = 0; v < vertexCount; ++v) pushVertex(uint32_t(v), wn[v], normalMapped ? wt[v] : glm::vec4(0, 0, 0, 1));
        for (glm::uvec3 t : tris) {
            if (flipWinding) std::swap(t.y, t.z);
            glm::vec3 e1 = wp[t.y] - wp[t.x], e2 = wp[t.z] - wp[t.x];
            glm::vec3 c = glm::cross(e1, e2);
            float len = glm::length(c);
            if (!(len > 0.0f) || !std::isfinite(len)) {
                ++scene_.stats.degenerateTrianglesDropped;
                continue;
            }
            if (flat) {
                glm::vec3 n = c / len;
                glm::vec4 tg[3] = {glm::vec4(0, 0, 0, 1), glm::vec4(0, 0, 0, 1), glm::vec4(0, 0, 0, 1)};
                if (normalMapped && tan.empty()) {
                    glm::vec3 dpdu, dpdv;
                    triangleTangents(t, dpdu, dpdv);
                    tg[0] = tg[1] = tg[2] = frame(n, dpdu, dpdv);
                } else if (normalMapped) {
                    tg[0] = wt[t.x], tg[1] = wt[t.y], tg[2] = wt[t.z];
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

    std::string path_;
    tinygltf::Model& model_;
    Scene& scene_;
    std::map<std::pair<int, bool>, int> textureCache_;
    int defaultMaterial_ = -1;
};

bool hasGlbMagic(const std::string& path) {
    std::ifstream f(path, std::ios::binary);
    char magic[4] = {};
    f.read(magic, 4);
    return f.gcount() == 4 && std::memcmp(magic, "glTF", 4) == 0;
}

// tinygltf decodes Draco while parsing and indexes bufferViews and accessors from the extension without
// bounds checks; check those indices in the JSON first so a hostile file cannot reach that code.
void checkDracoIndices(const std::string& path) {
    std::ifstream f(path, std::ios::binary);
    std::string bytes((std::istreambuf_iterator<char>(f)), std::istreambuf_iterator<char>());
    std::string text;
    if (bytes.size() >= 20 && std::memcmp(bytes.data(), "glTF", 4) == 0) {
        uint32_t chunkLength = 0, chunkType = 0;
        std::memcpy(&chunkLength, bytes.data() + 12, 4);
        std::memcpy(&chunkType, bytes.data() + 16, 4);
        if (chunkType != 0x4E4F534Au || chunkLength > bytes.size() - 20) return;  // tinygltf reports it
        text = bytes.substr(20, chunkLength);
    } else {
        text = std::move(bytes);
    }
    nlohmann::json doc = nlohmann::json::parse(text, nullptr, false);
    if (doc.is_discarded() || !doc.is_object() || !doc.contains("meshes") || !doc["meshes"].is_array()) return;
    auto count = [&](const char* key) { return doc.contains(key) && doc[key].is_array() ? doc[key].size() : size_t(0); };
    const size_t views = count("bufferViews"), accessors = count("accessors");
    auto validIndex = [](const nlohmann::json& v, size_t n) { return v.is_number_integer() && v.get<int64_t>() >= 0 && size_t(v.get<int64_t>()) < n; };
    for (size_t m = 0; m < doc["meshes"].size(); ++m) {
        const nlohmann::json& mesh = doc["meshes"][m];
        if (!mesh.is_object() || !mesh.contains("primitives") || !mesh["primitives"].is_array()) continue;
        for (size_t p = 0; p < mesh["primitives"].size(); ++p) {
            const nlohmann::json& prim = mesh["primitives"][p];
            if (!prim.is_object() || !prim.contains("extensions") || !prim["extensions"].is_object() ||
                !prim["extensions"].contains("KHR_draco_mesh_compression"))
                continue;
            const std::string where = path + ": mesh " + std::to_string(m) + " primitive " + std::to_string(p) + ": ";
            const nlohmann::json& draco = prim["extensions"]["KHR_draco_mesh_compression"];
            if (!draco.is_object() || !draco.contains("bufferView") || !validIndex(draco["bufferView"], views))
                throw SceneError(where + "KHR_draco_mesh_compression refers to a bufferView that does not exist");
            if (prim.contains("indices") && !validIndex(prim["indices"], accessors))
                throw SceneError(where + "indices refer to an accessor that does not exist");
            if (!prim.contains("attributes") || !prim["attributes"].is_object())
                throw SceneError(where + "has no attributes");
            for (auto& [name, index] : prim["attributes"].items())
                if (!validIndex(index, accessors))
                    throw SceneError(where + "attribute " + name + " refers to an accessor that does not exist");
            if (draco.contains("attributes") && draco["attributes"].is_object())
                for (auto& [name, id] : draco["attributes"].items())
                    if (!prim["attributes"].contains(name))
                        throw SceneError(where + "Draco attribute " + name + " is not an attribute of the primitive");
        }
    }
}

}  // namespace

Scene loadGltf(const std::string& path) {
    {
        std::ifstream probe(path, std::ios::binary);
        if (!probe) throw SceneError(path + ": cannot open file");
    }
    checkDracoIndices(path);
    tinygltf::TinyGLTF loader;
    tinygltf::Model model;
    std::string err, warn;
    bool ok = hasGlbMagic(path) ? loader.LoadBinaryFromFile(&model, &err, &warn, path)
                                : loader.LoadASCIIFromFile(&model, &err, &warn, path);
    if (!ok) throw SceneError(path + ": not a valid glTF file: " + trim(err.empty() ? warn : err));

    Scene scene;
    scene.sourcePath = path;
    if (!warn.empty()) scene.stats.warnings.push_back(trim(warn));
    Importer(path, model, scene).run();
    return scene;
}

}  // namespace nrad
