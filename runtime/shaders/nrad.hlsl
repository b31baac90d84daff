// libnrad's shading path for HLSL (Unreal, Unity, any D3D12 renderer; SPIR-V through glslang's or DXC's HLSL front
// end): the very source of nrad.glsl, which is written in the subset both languages share, with GLSL's names
// mapped to HLSL's here. The same functions, the same arithmetic, held to the CPU runtime by tests/gpu.
//
// Before including, optionally:
//   #define NRAD_ASSET_BINDING n      the buffer's Vulkan binding (default 0)
//   #define NRAD_ASSET_SET s          its Vulkan descriptor set (default 0)
//   #define NRAD_ASSET_REGISTER tN    its D3D register (default t0)
//   #define NRAD_NO_BUFFER_DECLARATION  and declare `StructuredBuffer<uint> nradWords` (or a ByteAddressBuffer
//                                       wrapper of that name with operator[]) yourself
//
// Then, as in nrad.glsl (vec3 is float3):
//   uint nradEvaluate(float3 position, float3 normal, float3 towardsViewer, out float3 radiance)
//   uint nradShade(float3 position, float3 normal, float3 towardsViewer, NradSurface surface, out float3 radiance)
//   uint nradEvaluateVolume(float3 position, float3 normal, out float3 radiance)
//   uint nradShadeVolume(float3 position, float3 normal, float3 towardsViewer, NradSurface surface, out float3 radiance)
#ifndef NRAD_HLSL
#define NRAD_HLSL 1

#ifndef NRAD_ASSET_BINDING
#define NRAD_ASSET_BINDING 0
#endif
#ifndef NRAD_ASSET_SET
#define NRAD_ASSET_SET 0
#endif
#ifndef NRAD_ASSET_REGISTER
#define NRAD_ASSET_REGISTER t0
#endif
#ifndef NRAD_NO_BUFFER_DECLARATION
[[vk::binding(NRAD_ASSET_BINDING, NRAD_ASSET_SET)]] StructuredBuffer<uint> nradWords : register(NRAD_ASSET_REGISTER);
#define NRAD_NO_BUFFER_DECLARATION
#endif

// GLSL's names in HLSL.
#define vec2 float2
#define vec3 float3
#define vec4 float4
#define bvec3 bool3
#define floatBitsToUint asuint
#define uintBitsToFloat asfloat
#define unpackHalf2x16(w) float2(f16tof32((w) & 0xFFFFu), f16tof32((w) >> 16u))
#define NRAD_CONST static const

#include "nrad.glsl"

#endif  // NRAD_HLSL
