// Voxel grid and surface pieces: clipped areas add up to the triangle areas, every sampled point lies in
// its piece's voxel, and a voxel is occupied exactly when a triangle passes through it.
#include "baker/bake/voxel_grid.h"

#include <cmath>

#include <gtest/gtest.h>

#include "baker/nn/mlp.h"
#include "baker/scene/gltf_loader.h"
#include "support/test_paths.h"

namespace nrad {
namespace {

TEST(VoxelGrid, ClippedAreasSumToTheSurfaceArea) {
    for (const char* scene : {"scenes/cornell-box/cornell-box.gltf", "scenes/cornell-box-glossy/cornell-box-glossy.gltf"}) {
        Scene s = loadGltf(test::sourcePath(scene));
        double area = 0.0;
        for (size_t t = 0; t < s.mesh.triangleCount(); ++t) area += s.mesh.triangleArea(t);
        for (glm::uvec3 dims : {glm::uvec3(1), glm::uvec3(3), glm::uvec3(7, 2, 5)}) {
            VoxelGrid grid(s.bounds, dims);
            SurfacePieces pieces(s.mesh, grid);
            EXPECT_NEAR(pieces.totalArea(), area, 1e-5 * area) << scene;
            double sum = 0.0;
            for (double a : pieces.voxelArea()) sum += a;
            EXPECT_NEAR(sum, area, 1e-5 * area);
        }
    }
}

TEST(VoxelGrid, SampledPointsLieInTheirVoxel) {
    Scene s = loadGltf(test::sourcePath("scenes/cornell-box/cornell-box.gltf"));
    VoxelGrid grid(s.bounds, glm::uvec3(4, 3, 5));
    SurfacePieces pieces(s.mesh, grid);
    SplitMix64 rng(1);
    for (const SurfacePiece& piece : pieces.pieces())
        for (int i = 0; i < 20; ++i) {
            float b1, b2;
            glm::vec3 p = pieces.samplePiece(piece, {rng.uniform(), rng.uniform()}, b1, b2);
            Bounds3 vb = grid.voxelBounds(piece.voxel);
            glm::vec3 tol = 1e-5f * (vb.upper - vb.lower);
            ASSERT_TRUE(glm::all(glm::greaterThanEqual(p, vb.lower - tol)) && glm::all(glm::lessThanEqual(p, vb.upper + tol)));
            // The barycentrics reproduce the point on the original triangle.
            const glm::uvec3& t = s.mesh.triangles[piece.triangle];
            glm::vec3 q = (1 - b1 - b2) * s.mesh.positions[t.x] + b1 * s.mesh.positions[t.y] + b2 * s.mesh.positions[t.z];
            ASSERT_LT(glm::length(q - p), 1e-5f);
        }
}

TEST(VoxelGrid, EmptyVoxelsHaveNoPieces) {
    // In a 5x5x5 grid over the Cornell box, the voxels that no triangle touches (checked here with an
    // independent separating-axis triangle/box test) must have no pieces, and all others must have some.
    Scene s = loadGltf(test::sourcePath("scenes/cornell-box/cornell-box.gltf"));
    VoxelGrid grid(s.bounds, glm::uvec3(5));
    SurfacePieces pieces(s.mesh, grid);
    auto overlaps = [](const glm::vec3 v[3], const Bounds3& b) {
        glm::vec3 c = b.center(), h = 0.5f * b.extent();
        glm::vec3 p[3] = {v[0] - c, v[1] - c, v[2] - c};
        glm::vec3 e[3] = {p[1] - p[0], p[2] - p[1], p[0] - p[2]};
        auto separated = [&](const glm::vec3& axis) {
            float a = glm::dot(p[0], axis), bb = glm::dot(p[1], axis), cc = glm::dot(p[2], axis);
            float r = h.x * std::abs(axis.x) + h.y * std::abs(axis.y) + h.z * std::abs(axis.z);
            return std::min(a, std::min(bb, cc)) > r || std::max(a, std::max(bb, cc)) < -r;
        };
        for (int k = 0; k < 3; ++k) {
            glm::vec3 axis(0.0f);
            axis[k] = 1.0f;
            if (separated(axis)) return false;
            for (const glm::vec3& edge : e)
                if (glm::length(glm::cross(axis, edge)) > 0.0f && separated(glm::cross(axis, edge))) return false;
        }
        return !separated(glm::cross(e[0], e[1]));
    };
    int empty = 0;
    for (uint32_t v = 0; v < grid.voxelCount(); ++v) {
        Bounds3 b = grid.voxelBounds(v);
        bool touched = false;
        for (size_t t = 0; t < s.mesh.triangleCount() && !touched; ++t) {
            const glm::uvec3& tri = s.mesh.triangles[t];
            glm::vec3 vs[3] = {s.mesh.positions[tri.x], s.mesh.positions[tri.y], s.mesh.positions[tri.z]};
            // Shrink the box a little: a triangle merely touching a face has no area inside.
            Bounds3 inner = b;
            inner.lower += 1e-4f * b.extent();
            inner.upper -= 1e-4f * b.extent();
            touched = overlaps(vs, inner);
        }
        EXPECT_EQ(!pieces.piecesOf(v).empty(), touched) << "voxel " << v;
        empty += touched ? 0 : 1;
    }
    EXPECT_GT(empty, 10);  // the box's interior is mostly empty
}

}  // namespace
}  // namespace nrad
