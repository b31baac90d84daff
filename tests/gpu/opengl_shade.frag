// An OpenGL 4.50 fragment shader shading from a G-buffer with runtime/shaders/nrad.glsl (compiled, not run,
// by the glsl_include_compiles_for_opengl test): the include needs nothing Vulkan-specific.
#version 450
#extension GL_GOOGLE_include_directive : require
#define NRAD_ASSET_BINDING 3
#include "nrad.glsl"

layout(binding = 0) uniform sampler2D gPosition;
layout(binding = 1) uniform sampler2D gNormal;
layout(binding = 2) uniform sampler2D gBaseColorMetallic;
layout(binding = 0, std140) uniform View { vec3 eye; };
layout(location = 0) out vec4 color;

void main() {
    ivec2 px = ivec2(gl_FragCoord.xy);
    vec3 p = texelFetch(gPosition, px, 0).xyz;
    vec3 n = normalize(texelFetch(gNormal, px, 0).xyz);
    vec4 bm = texelFetch(gBaseColorMetallic, px, 0);
    NradSurface s = NradSurface(bm.rgb, bm.a, texelFetch(gNormal, px, 0).w, 1.0, vec3(0.0));
    vec3 v = normalize(eye - p);
    vec3 rgb;
    nradShade(p, dot(n, v) < 0.0 ? -n : n, v, s, rgb);
    color = vec4(rgb, 1.0);
}
