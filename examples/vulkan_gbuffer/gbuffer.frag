// G-buffer pass, fragment stage: what an engine's G-buffer holds, in four RGBA32F targets: position and
// coverage (1, or 2 for an object that was not in the bake), the shading normal on the viewer's side and roughness, base colour and metallic, emission towards
// the viewer and the specular factor. The normal rules are the baker's (makeInteraction): vertex normals on
// the winding side, both normals flipped to the viewer's side, the geometric normal where the shading one
// faces away.
#version 450

struct Triangle {
    vec4 geometricNormal;  // xyz, from the winding order; w 1: an object that was not in the bake (a moving one)
    vec4 baseColorMetallic;
    vec4 emissionFrontRoughness;  // emission seen from the front; w roughness
    vec4 emissionBackSpecular;  // emission seen from the back (double-sided emitters); w specular factor
};
layout(std430, set = 0, binding = 1) readonly buffer Triangles { Triangle triangles[]; };

layout(push_constant) uniform View {
    mat4 clipFromWorld;
    vec4 eye;
} view;

layout(location = 0) in vec3 worldPosition;
layout(location = 1) in vec3 shadingNormal;
layout(location = 2) flat in uint triangle;

layout(location = 0) out vec4 gPosition;
layout(location = 1) out vec4 gNormalRoughness;
layout(location = 2) out vec4 gBaseColorMetallic;
layout(location = 3) out vec4 gEmissionSpecular;

void main() {
    Triangle t = triangles[triangle];
    vec3 wo = view.eye.w != 0.0 ? normalize(view.eye.xyz - worldPosition) : -view.eye.xyz;
    vec3 ng = t.geometricNormal.xyz;
    float len = length(shadingNormal);
    vec3 ns = len > 1e-6 ? shadingNormal / len : ng;
    if (dot(ns, ng) < 0.0) ns = -ns;
    bool front = dot(ng, wo) >= 0.0;
    if (!front) {
        ng = -ng;
        ns = -ns;
    }
    if (dot(ns, wo) <= 0.0) ns = ng;
    gPosition = vec4(worldPosition, t.geometricNormal.w > 0.5 ? 2.0 : 1.0);  // w: coverage, 2 for a moving object
    gNormalRoughness = vec4(ns, t.emissionFrontRoughness.w);
    gBaseColorMetallic = t.baseColorMetallic;
    gEmissionSpecular = vec4(front ? t.emissionFrontRoughness.xyz : t.emissionBackSpecular.xyz, t.emissionBackSpecular.w);
}
