// Scene: the project's own, library-free description of what the baker renders. Everything is flattened
// into world space (instances expanded), so renderers never see glTF or its node hierarchy.
#pragma once

#include <cstdint>
#include <limits>
#include <string>
#include <vector>

#include <glm/glm.hpp>

#include "baker/scene/environment.h"
#include "baker/scene/texture.h"
#include "baker/util/maths.h"

namespace nrad {

// Luminous efficacy that turns photometric light units (glTF's candela and lux) into radiometric ones
// (docs/lights.md): the SI definition of the candela.
constexpr float kLumensPerWatt = 683.0f;

// Luminance of a linear Rec. 709 colour: how lights' power and maps' brightness are weighed.

struct Bounds3 {
    glm::vec3 lower{std::numeric_limits<float>::infinity()};
    glm::vec3 upper{-std::numeric_limits<float>::infinity()};

    void extend(const glm::vec3& p) {
        lower = glm::min(lower, p);
        upper = glm::max(upper, p);
    }
    bool empty() const { return !(lower.x <= upper.x && lower.y <= upper.y && lower.z <= upper.z); }
    glm::vec3 center() const { return 0.5f * (lower + upper); }
    glm::vec3 extent() const { return upper - lower; }
    // Radius of the bounding sphere around center().
    float radius() const { return empty() ? 0.0f : 0.5f * glm::length(extent()); }
};

// A reference to a texture from a material slot, with the UV set it reads and its KHR_texture_transform
// (uv' = offset + R(rotation) (scale * uv), R = [cos sin; -sin cos] as the extension defines it).
struct TextureRef {
    int texture = -1;  // index into Scene::textures, -1 = none
    int texCoord = 0;  // 0 or 1
    glm::vec2 offset{0.0f};
    float rotation = 0.0f;  // radians
    glm::vec2 scale{1.0f};
    bool valid() const { return texture >= 0; }
    bool transformed() const { return offset != glm::vec2(0.0f) || rotation != 0.0f || scale != glm::vec2(1.0f); }
    glm::vec2 apply(glm::vec2 uv) const;
};

// glTF 2.0 metallic-roughness material (plus KHR_materials_emissive_strength and KHR_materials_specular).
struct Material {
    std::string name;
    glm::vec3 baseColor{1.0f};  // linear RGB
    TextureRef baseColorTexture;  // sRGB-decoded on load
    float metallic = 1.0f;
    float roughness = 1.0f;  // perceptual roughness; GGX alpha = roughness^2
    TextureRef metallicRoughnessTexture;  // G = roughness, B = metallic (linear)
    glm::vec3 emission{0.0f};  // emissiveFactor x emissive_strength: radiance in scene units
    TextureRef emissiveTexture;  // sRGB-decoded
    float specular = 1.0f;  // KHR_materials_specular specularFactor (0 = pure Lambertian dielectric)
    glm::vec3 specularColor{1.0f};  // KHR_materials_specular specularColorFactor
    float ior = 1.5f;
    bool doubleSided = false;
    // KHR_materials_transmission, thin-walled (no KHR_materials_volume): the share of the dielectric base that
    // passes through the surface instead of being diffusely reflected (factor x texture's red channel).
    float transmission = 0.0f;
    TextureRef transmissionTexture;
    TextureRef normalTexture;  // tangent space, linear
    float normalScale = 1.0f;
    // Coverage: OPAQUE ignores alpha; MASK cuts out where alpha < alphaCutoff (light passes through the holes);
    // BLEND is stochastic coverage (a ray passes with probability 1 - alpha; docs/rendering.md).
    enum class AlphaMode { Opaque, Mask, Blend };
    AlphaMode alphaMode = AlphaMode::Opaque;
    float alpha = 1.0f;  // baseColorFactor's fourth component
    float alphaCutoff = 0.5f;

    bool emissive() const { return emission.x > 0.0f || emission.y > 0.0f || emission.z > 0.0f; }
};

// Photometric glTF lights, already converted to radiometric quantities (see docs/lights.md).
struct PunctualLight {
    enum class Type { Point, Spot, Directional };
    Type type = Type::Point;
    std::string name;
    glm::vec3 position{0.0f};  // world space (point, spot)
    glm::vec3 direction{0.0f, 0.0f, -1.0f};  // world space, the direction light travels (spot, directional)
    // Point/spot: radiant intensity [W/sr]. Directional: irradiance on a perpendicular surface [W/m^2].
    glm::vec3 intensity{0.0f};
    float cosInnerCone = 1.0f;  // spot only
    float cosOuterCone = 0.0f;  // spot only
    // Directional only: cosine of the angular radius of the light's disk (a sun 0.53 degrees across: 0.99998929).
    // 1 = a sharp (delta) light; below 1 a disk of uniform radiance E / (pi sin^2 radius), sampled over its
    // cone, seen by rays that leave the scene: soft shadows.
    float cosAngularRadius = 1.0f;
    // Mixed lighting: the engine draws this light's direct contribution at run time (with its own shadows);
    // the asset holds only its indirect light (docs/lights.md).
    bool runtimeDirect = false;
    bool soft() const { return type == Type::Directional && cosAngularRadius < 1.0f; }
};

struct Camera {
    enum class Type { Perspective, Orthographic };
    Type type = Type::Perspective;
    std::string name;
    glm::vec3 position{0.0f};
    glm::mat3 worldFromCamera{1.0f};  // columns: right, up, backwards (the camera looks down -Z)
    float yfov = 0.7854f;  // perspective, radians
    float aspectRatio = 0.0f;  // 0 = take it from the image size
    float xmag = 1.0f, ymag = 1.0f;  // orthographic half extents
};

// Flattened triangle geometry in world space. Vertices are per instance (no sharing across instances).
struct TriangleMesh {
    std::vector<glm::vec3> positions;
    std::vector<glm::vec3> normals;  // unit length, one per vertex
    std::vector<glm::vec2> uv0, uv1;  // one per vertex (zero when the primitive had none)
    // Optional per-vertex attributes: empty when no primitive has them, else one per vertex (defaults for the
    // primitives without: colour 1, tangent (0, 0, 0, 1) = none).
    std::vector<glm::vec4> colors;  // COLOR_0, linear RGBA: multiplies the base colour and alpha
    std::vector<glm::vec4> tangents;  // xyz unit tangent in world space, w = +-1 bitangent sign (glTF TANGENT)
    std::vector<glm::uvec3> triangles;  // indices into the vertex arrays
    std::vector<uint32_t> materialIds;  // one per triangle, index into Scene::materials

    size_t triangleCount() const { return triangles.size(); }
    float triangleArea(size_t t) const;
    glm::vec3 geometricNormal(size_t t) const;  // unit, from the winding order
};

// What the importer did, for the user and for tests.
struct ImportStats {
    size_t nodesVisited = 0;
    size_t meshInstances = 0;
    size_t primitives = 0;
    size_t trianglesRead = 0;  // before dropping degenerate ones
    size_t degenerateTrianglesDropped = 0;
    size_t primitivesWithGeneratedNormals = 0;
    size_t primitivesWithGeneratedTangents = 0;  // normal-mapped primitives without TANGENT
    size_t primitivesSkipped = 0;  // points and lines: nothing to render
    size_t dracoPrimitives = 0;
    std::vector<std::string> warnings;
};

struct Scene {
    std::string sourcePath;
    TriangleMesh mesh;
    std::vector<Material> materials;  // never empty after import (a default material is added if needed)
    std::vector<Texture> textures;
    std::vector<PunctualLight> lights;
    std::vector<Camera> cameras;
    Environment environment;  // not from glTF: set by the commands (--environment, or the default sky)
    Bounds3 bounds;
    ImportStats stats;
    // Objects placed after the bake (`--insert`, issue 42): the first triangle of each, in order; the triangles
    // from insertedObjects[0] on are none of the bake's (they are shaded through the asset's volume query).
    std::vector<size_t> insertedObjects;
    std::vector<std::string> insertedNames;  // what each was placed from ("FILE@x,y,z")

    // The inserted object triangle t belongs to, -1 for the bake's own triangles.
    int insertedObject(size_t t) const;

    // Recomputes bounds from the mesh and the positional lights.
    void updateBounds();
    // Triangles that emit light: positive emitted power (their emission averaged over their texture).
    size_t emissiveTriangleCount() const;
    // The mean emitted radiance of triangle t (front side): the material's emission times its emissive texture
    // averaged over the triangle's footprint in the texture (the centroids of n^2 equal sub-triangles,
    // n = 1..16 growing with the texels the triangle covers). Zero for non-emissive materials.
    glm::vec3 triangleEmission(size_t t) const;
    // Whether anything lights the scene: an emitter of positive power, a punctual light of positive
    // intensity, or an active environment.
    bool hasLight() const;
};

// Places `object` (another imported scene) into `scene`, moved by `offset`: its triangles are appended (with its
// materials and textures), recorded in insertedObjects. Its punctual lights and cameras are not taken (an object
// placed after the bake lights nothing the asset holds). Throws SceneError for an object without triangles, or one
// whose vertices would take the scene past 2^32 - 1.
void insertObject(Scene& scene, const Scene& object, const glm::vec3& offset, const std::string& name);

// The scene as it was before insertObject: the inserted objects' triangles and vertices dropped (their materials
// and textures stay, unused).
Scene withoutInsertedObjects(const Scene& scene);

// Builds a camera that frames the whole scene from +Z looking down -Z (used when the scene has none).
Camera frameBounds(const Bounds3& bounds, float yfov = 0.6911f);

}  // namespace nrad
