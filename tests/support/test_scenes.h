// Scenes built in code for analytic tests: a closed emitting sphere (furnace) and a lit plane.
#pragma once

#include "baker/scene/scene.h"

namespace nrad::test {

// A closed UV sphere of radius `radius` around the origin with smooth radial normals, one double-sided
// material `material`, and a camera at the centre looking down -Z with a 90-degree field of view.
Scene makeSphereFurnace(const Material& material, float radius = 1.0f, int segments = 64);

// A square Lambertian plane z = 0 of half-size `halfSize` (albedo `albedo`, specular 0) and an orthographic
// camera above it looking straight down; lights are added by the caller.
Scene makeLitPlane(float albedo, float halfSize = 10.0f);

}  // namespace nrad::test
