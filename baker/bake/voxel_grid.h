// VoxelGrid: the axis-aligned grid over the scene bounds, and the scene's surface cut into pieces that lie
// in exactly one voxel each (triangles clipped against voxel boxes), so surface points can be sampled
// uniformly by area over the whole scene or within one voxel, and empty voxels are known exactly.
#pragma once

#include <cstdint>
#include <vector>

#include <glm/glm.hpp>
#include <nrad/eval.h>
#include <nrad/format.h>

#include "baker/scene/scene.h"

namespace nrad {

class VoxelGrid {
public:
    // Covers `bounds` (padded slightly so every surface point is inside; flat axes get a minimum extent).
    VoxelGrid(const Bounds3& bounds, glm::uvec3 dims);

    const format::Grid& grid() const { return grid_; }
    glm::uvec3 dims() const { return {grid_.dims[0], grid_.dims[1], grid_.dims[2]}; }
    uint32_t voxelCount() const { return grid_.dims[0] * grid_.dims[1] * grid_.dims[2]; }
    // Voxel holding p (the format's rule, shared with the runtime), or -1 outside.
    int64_t voxelOf(const glm::vec3& p) const;
    glm::ivec3 coordOf(uint32_t voxel) const;
    Bounds3 voxelBounds(uint32_t voxel) const;
    // p mapped to [-1, 1]^3 inside its voxel (the network's position input).
    glm::vec3 positionInVoxel(const glm::vec3& p, uint32_t voxel) const;

private:
    format::Grid grid_;
};

// A convex polygon (up to 9 vertices) of one triangle inside one voxel.
struct SurfacePiece {
    uint32_t triangle;
    uint32_t voxel;
    float area;
    uint8_t vertexCount;  // 3 and vertices == the triangle when the triangle lies in one voxel
    glm::vec3 vertices[9];
};

// The scene's triangles clipped against the grid. Degenerate slivers give no pieces.
class SurfacePieces {
public:
    SurfacePieces(const TriangleMesh& mesh, const VoxelGrid& grid);

    const std::vector<SurfacePiece>& pieces() const { return pieces_; }
    const std::vector<double>& voxelArea() const { return voxelArea_; }
    double totalArea() const { return totalArea_; }
    // Indices of the pieces in `voxel`, in a fixed order.
    const std::vector<uint32_t>& piecesOf(uint32_t voxel) const { return byVoxel_[voxel]; }

    // Uniform point on a piece from u (2D), returned with the barycentrics (b1, b2) on its triangle.
    glm::vec3 samplePiece(const SurfacePiece& piece, glm::vec2 u, float& b1, float& b2) const;

private:
    const TriangleMesh& mesh_;
    std::vector<SurfacePiece> pieces_;
    std::vector<std::vector<uint32_t>> byVoxel_;
    std::vector<double> voxelArea_;
    double totalArea_ = 0.0;
};

}  // namespace nrad
