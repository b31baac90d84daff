// Geometry the renderer and the lights share: an orthonormal frame around a normal, and the distances beyond
// the rounding of a point's and a triangle's coordinates.
#pragma once

#include <cstdint>

#include <glm/glm.hpp>

#include "baker/scene/scene.h"

namespace nrad {

// Orthonormal frame around a unit normal; toLocal maps the normal to +Z.
struct Frame {
    glm::vec3 s, t, n;
    static Frame fromNormal(const glm::vec3& n);
    glm::vec3 toLocal(const glm::vec3& v) const { return {glm::dot(v, s), glm::dot(v, t), glm::dot(v, n)}; }
    glm::vec3 toWorld(const glm::vec3& v) const { return s * v.x + t * v.y + n * v.z; }
};

// A few hundred float ulps of the largest coordinate magnitude of p (with a floor near the origin): a
// distance beyond the rounding of anything computed from coordinates of that size, at any scene scale.
float rayOffset(const glm::vec3& p);

// Margin around triangle t's plane within which a ray leaving (or aiming at) a point of it does not look
// for hits: rayOffset of the largest coordinate of its three vertices. Both the rounding of a point
// interpolated on the triangle and Embree's rounding of a ray's distance to its plane scale with its
// vertices' coordinates, not the point's: a margin from the point's own coordinates let shadow rays near the
// origin find their own triangle (docs/design.md).
float triangleMargin(const TriangleMesh& mesh, uint32_t t);

}  // namespace nrad
