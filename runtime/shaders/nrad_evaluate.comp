// Evaluates (or shades) a batch of points with an asset packed by nradPackGpuBuffer: the GPU counterpart of
// nradEvaluateBatch / nradShadeBatch, for validation and benchmarks (tests/gpu). Bindings, all std430 storage
// buffers in set 0: 0 the packed asset; 1 positions, 2 normals, 3 directions (3 floats per point, interleaved
// xyz); 4 surfaces (9 floats per point, nrad.h's NradSurface: base colour, metallic, roughness, specular,
// emission; read only when shading); 5 radiance out (3 floats per point); 6 flags out (a uint per point).
// Push constants: the count and the mode: 0 evaluate, 1 shade (the surfaces' networks), 2 evaluate, 3 shade the light
// in the volume (nradEvaluateVolume, nradShadeVolume: receivers that were not in the bake; directions only shade). Dispatch ceil(count / 64) workgroups along x (Vulkan
// guarantees 65,535: up to 4,194,240 points per dispatch; split larger batches).
#version 450
#extension GL_GOOGLE_include_directive : require

layout(local_size_x = 64) in;

#define NRAD_ASSET_BINDING 0
#include "nrad.glsl"

layout(std430, set = 0, binding = 1) readonly buffer Positions { float positions[]; };
layout(std430, set = 0, binding = 2) readonly buffer Normals { float normals[]; };
layout(std430, set = 0, binding = 3) readonly buffer Directions { float directions[]; };
layout(std430, set = 0, binding = 4) readonly buffer Surfaces { float surfaces[]; };
layout(std430, set = 0, binding = 5) writeonly buffer Radiance { float radiance[]; };
layout(std430, set = 0, binding = 6) writeonly buffer Flags { uint flags[]; };

layout(push_constant) uniform Batch {
    uint count;
    uint mode;
} batch;

vec3 load3(uint i, uint which) {
    if (which == 0u) return vec3(positions[3u * i], positions[3u * i + 1u], positions[3u * i + 2u]);
    if (which == 1u) return vec3(normals[3u * i], normals[3u * i + 1u], normals[3u * i + 2u]);
    return vec3(directions[3u * i], directions[3u * i + 1u], directions[3u * i + 2u]);
}

void main() {
    uint i = gl_GlobalInvocationID.x;
    if (i >= batch.count) return;
    vec3 p = load3(i, 0u), n = load3(i, 1u), d = load3(i, 2u);
    vec3 rgb;
    uint f;
    if ((batch.mode & 1u) != 0u) {
        uint s = 9u * i;
        NradSurface surface;
        surface.baseColor = vec3(surfaces[s], surfaces[s + 1u], surfaces[s + 2u]);
        surface.metallic = surfaces[s + 3u];
        surface.roughness = surfaces[s + 4u];
        surface.specular = surfaces[s + 5u];
        surface.emission = vec3(surfaces[s + 6u], surfaces[s + 7u], surfaces[s + 8u]);
        if (batch.mode == 3u) f = nradShadeVolume(p, n, d, surface, rgb);
        else f = nradShade(p, n, d, surface, rgb);
    } else if (batch.mode == 2u) {
        f = nradEvaluateVolume(p, n, rgb);
    } else {
        f = nradEvaluate(p, n, d, rgb);
    }
    radiance[3u * i] = rgb.x;
    radiance[3u * i + 1u] = rgb.y;
    radiance[3u * i + 2u] = rgb.z;
    flags[i] = f;
}
