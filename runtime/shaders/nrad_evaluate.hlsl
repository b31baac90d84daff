// nrad_evaluate.comp in HLSL: the same bindings, push constants and modes, through nrad.hlsl (tests/gpu runs both
// against the CPU runtime). Compile: glslangValidator -D -V -S comp -e main -I<this folder> nrad_evaluate.hlsl
#define NRAD_ASSET_BINDING 0
#include "nrad.hlsl"

[[vk::binding(1, 0)]] StructuredBuffer<float> positions : register(t1);
[[vk::binding(2, 0)]] StructuredBuffer<float> normals : register(t2);
[[vk::binding(3, 0)]] StructuredBuffer<float> directions : register(t3);
[[vk::binding(4, 0)]] StructuredBuffer<float> surfaces : register(t4);
[[vk::binding(5, 0)]] RWStructuredBuffer<float> radiance : register(u0);
[[vk::binding(6, 0)]] RWStructuredBuffer<uint> flags : register(u1);

struct Batch {
    uint count;
    uint mode;  // 0 evaluate, 1 shade, 2 evaluate the light in the volume, 3 shade it
};
[[vk::push_constant]] Batch batch;

float3 load3(StructuredBuffer<float> b, uint i) { return float3(b[3u * i], b[3u * i + 1u], b[3u * i + 2u]); }

[numthreads(64, 1, 1)]
void main(uint3 id : SV_DispatchThreadID) {
    uint i = id.x;
    if (i >= batch.count) return;
    float3 p = load3(positions, i), n = load3(normals, i), d = load3(directions, i);
    float3 rgb;
    uint f;
    if ((batch.mode & 1u) != 0u) {
        uint s = 9u * i;
        NradSurface surface;
        surface.baseColor = float3(surfaces[s], surfaces[s + 1u], surfaces[s + 2u]);
        surface.metallic = surfaces[s + 3u];
        surface.roughness = surfaces[s + 4u];
        surface.specular = surfaces[s + 5u];
        surface.emission = float3(surfaces[s + 6u], surfaces[s + 7u], surfaces[s + 8u]);
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
