// The shading pass an engine adds: every covered G-buffer pixel shaded with the asset (runtime/shaders/nrad.glsl),
// the baked surfaces by nradShade, moving objects (coverage 2) by nradShadeVolume,
// written to an RGBA32F image; uncovered pixels get 0 (the engine draws its sky there).
#version 450
#extension GL_GOOGLE_include_directive : require

layout(local_size_x = 8, local_size_y = 8) in;

#define NRAD_ASSET_SET 0
#define NRAD_ASSET_BINDING 0
#include "nrad.glsl"

layout(set = 0, binding = 1, rgba32f) uniform readonly image2D gPosition;
layout(set = 0, binding = 2, rgba32f) uniform readonly image2D gNormalRoughness;
layout(set = 0, binding = 3, rgba32f) uniform readonly image2D gBaseColorMetallic;
layout(set = 0, binding = 4, rgba32f) uniform readonly image2D gEmissionSpecular;
layout(set = 0, binding = 5, rgba32f) uniform writeonly image2D shaded;

layout(push_constant) uniform View {
    mat4 clipFromWorld;
    vec4 eye;
} view;

void main() {
    ivec2 px = ivec2(gl_GlobalInvocationID.xy);
    if (any(greaterThanEqual(px, imageSize(shaded)))) return;
    vec4 p = imageLoad(gPosition, px);
    if (p.w == 0.0) {
        imageStore(shaded, px, vec4(0.0));
        return;
    }
    vec4 nr = imageLoad(gNormalRoughness, px), bm = imageLoad(gBaseColorMetallic, px), es = imageLoad(gEmissionSpecular, px);
    vec3 wo = view.eye.w != 0.0 ? normalize(view.eye.xyz - p.xyz) : -view.eye.xyz;
    NradSurface s = NradSurface(bm.rgb, bm.a, nr.w, es.w, es.rgb);
    vec3 rgb;
    if (p.w > 1.5) nradShadeVolume(p.xyz, nr.xyz, wo, s, rgb);  // a moving object: the light in the volume
    else nradShade(p.xyz, nr.xyz, wo, s, rgb);
    imageStore(shaded, px, vec4(rgb, 1.0));
}
