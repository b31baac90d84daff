// G-buffer pass, vertex stage: positions and normals from a storage buffer (no vertex input state), the
// camera's projection in push constants.
#version 450

struct Vertex {
    vec4 position;  // xyz
    vec4 normal;  // xyz, the shading normal
};
layout(std430, set = 0, binding = 0) readonly buffer Vertices { Vertex vertices[]; };

layout(push_constant) uniform View {
    mat4 clipFromWorld;
    vec4 eye;  // xyz; w = 1 perspective, 0 orthographic (then xyz is the viewing direction)
} view;

layout(location = 0) out vec3 worldPosition;
layout(location = 1) out vec3 shadingNormal;
layout(location = 2) flat out uint triangle;

void main() {
    Vertex v = vertices[gl_VertexIndex];
    worldPosition = v.position.xyz;
    shadingNormal = v.normal.xyz;
    triangle = uint(gl_VertexIndex) / 3u;
    gl_Position = view.clipFromWorld * vec4(v.position.xyz, 1.0);
}
