// Scenes built in code for analytic tests: a closed emitting sphere (furnace) and a lit plane.
#pragma once

#include "baker/bake/baker.h"
#include "baker/render/image_io.h"
#include "baker/scene/scene.h"

namespace nrad::test {

// A closed, watertight UV sphere of radius `radius` around the origin, one double-sided material
// `material`, and a camera at the centre looking down -Z with a 90-degree field of view. Flat shading
// normals by default: smooth vertex normals make cosine-sampled directions fall below the facets now and
// then, which loses energy (about 0.03% per bounce at 64 segments, 3% of the radiance at albedo 0.99).
Scene makeSphereFurnace(const Material& material, float radius = 1.0f, int segments = 64, bool smoothNormals = false);

// A square Lambertian plane z = 0 of half-size `halfSize` (albedo `albedo`, specular 0) and an orthographic
// camera above it looking straight down; lights are added by the caller.
Scene makeLitPlane(float albedo, float halfSize = 10.0f);

// Eight black 1 cm triangles at the corners of a 2 m cube around the origin: the scene's bounds, and next to
// nothing that occludes or reflects. A receiver inside is lit by the environment and the lights alone.
Scene makeScaffold();

// Path traces scene.cameras[0] into a size x size image (NEE by power, MIS; maxDepth 0 = unbounded).
Image renderPathTraced(const Scene& scene, int size, int spp, int maxDepth = 0, uint32_t seed = 1, int tileSize = 16);

// The encoded asset of bakeScene(scene, settings) with `threads` worker threads.
std::vector<uint8_t> bakeBytes(const Scene& scene, const BakeSettings& settings, int threads);

}  // namespace nrad::test
