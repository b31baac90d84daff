// Voxel grid and the triangle-voxel clipping (Sutherland-Hodgman against the six box planes).
#include "baker/bake/voxel_grid.h"

#include <algorithm>
#include <cmath>

namespace nrad {

VoxelGrid::VoxelGrid(const Bounds3& bounds, glm::uvec3 dims) {
    glm::vec3 lo = bounds.empty() ? glm::vec3(-1.0f) : bounds.lower;
    glm::vec3 hi = bounds.empty() ? glm::vec3(1.0f) : bounds.upper;
    glm::vec3 extent = hi - lo;
    float maxExtent = std::max(extent.x, std::max(extent.y, extent.z));
    if (!(maxExtent > 0.0f)) maxExtent = std::max(1.0f, std::abs(lo.x));
    for (int k = 0; k < 3; ++k) {
        // A flat axis (a plane) still needs a voxel of some thickness; pad every axis by a small margin so
        // vertices on the bounds are inside after float rounding.
        float e = std::max(extent[k], 1e-3f * maxExtent);
        float c = 0.5f * (lo[k] + hi[k]);
        float half = 0.5f * e * (1.0f + 1e-4f) + 1e-6f * std::max(std::abs(lo[k]), std::abs(hi[k]));
        grid_.lower[k] = c - half;
        grid_.upper[k] = c + half;
        grid_.dims[k] = std::max(1u, dims[k]);
    }
}

int64_t VoxelGrid::voxelOf(const glm::vec3& p) const {
    float q[3] = {p.x, p.y, p.z};
    return eval::locate(grid_, q).voxel;
}

glm::ivec3 VoxelGrid::coordOf(uint32_t voxel) const {
    int x = int(voxel % grid_.dims[0]);
    int y = int((voxel / grid_.dims[0]) % grid_.dims[1]);
    int z = int(voxel / (grid_.dims[0] * grid_.dims[1]));
    return {x, y, z};
}

Bounds3 VoxelGrid::voxelBounds(uint32_t voxel) const {
    glm::ivec3 c = coordOf(voxel);
    Bounds3 b;
    for (int k = 0; k < 3; ++k) {
        float size = (grid_.upper[k] - grid_.lower[k]) / float(grid_.dims[k]);
        b.lower[k] = grid_.lower[k] + size * float(c[k]);
        b.upper[k] = c[k] + 1 == int(grid_.dims[k]) ? grid_.upper[k] : grid_.lower[k] + size * float(c[k] + 1);
    }
    return b;
}

glm::vec3 VoxelGrid::positionInVoxel(const glm::vec3& p, uint32_t voxel) const {
    glm::ivec3 c = coordOf(voxel);
    glm::vec3 out;
    for (int k = 0; k < 3; ++k)
        out[k] = eval::clampUnit(eval::localCoordinate(p[k], grid_.lower[k], eval::gridFactor(grid_, k), c[k]));
    return out;
}

namespace {

// Clips polygon `in` (n vertices) to the half-space sign * (p[axis] - plane) >= 0.
int clip(const glm::vec3* in, int n, glm::vec3* out, int axis, float plane, float sign) {
    int m = 0;
    for (int i = 0; i < n; ++i) {
        const glm::vec3& a = in[i];
        const glm::vec3& b = in[(i + 1) % n];
        float da = sign * (a[axis] - plane), db = sign * (b[axis] - plane);
        if (da >= 0.0f) out[m++] = a;
        if ((da >= 0.0f) != (db >= 0.0f)) {
            float t = da / (da - db);
            glm::vec3 p = a + t * (b - a);
            p[axis] = plane;  // exactly on the plane
            out[m++] = p;
        }
        if (m >= 9) break;  // a triangle clipped by 6 planes has at most 9 vertices
    }
    return m;
}

float polygonArea(const glm::vec3* v, int n) {
    glm::vec3 sum(0.0f);
    for (int i = 1; i + 1 < n; ++i) sum += glm::cross(v[i] - v[0], v[i + 1] - v[0]);
    return 0.5f * glm::length(sum);
}

}  // namespace

SurfacePieces::SurfacePieces(const TriangleMesh& mesh, const VoxelGrid& grid) : mesh_(mesh) {
    const format::Grid& g = grid.grid();
    byVoxel_.resize(grid.voxelCount());
    voxelArea_.assign(grid.voxelCount(), 0.0);
    glm::vec3 size;
    for (int k = 0; k < 3; ++k) size[k] = (g.upper[k] - g.lower[k]) / float(g.dims[k]);
    for (size_t t = 0; t < mesh.triangleCount(); ++t) {
        const glm::uvec3& tri = mesh.triangles[t];
        glm::vec3 p[3] = {mesh.positions[tri.x], mesh.positions[tri.y], mesh.positions[tri.z]};
        glm::ivec3 lo, hi;
        for (int k = 0; k < 3; ++k) {
            float mn = std::min(p[0][k], std::min(p[1][k], p[2][k])), mx = std::max(p[0][k], std::max(p[1][k], p[2][k]));
            lo[k] = std::clamp(int(std::floor((mn - g.lower[k]) / size[k])), 0, int(g.dims[k]) - 1);
            hi[k] = std::clamp(int(std::floor((mx - g.lower[k]) / size[k])), 0, int(g.dims[k]) - 1);
        }
        bool single = lo == hi;
        for (int z = lo.z; z <= hi.z; ++z)
            for (int y = lo.y; y <= hi.y; ++y)
                for (int x = lo.x; x <= hi.x; ++x) {
                    uint32_t voxel = uint32_t(x) + g.dims[0] * (uint32_t(y) + g.dims[1] * uint32_t(z));
                    SurfacePiece piece;
                    piece.triangle = uint32_t(t);
                    piece.voxel = voxel;
                    int n = 3;
                    glm::vec3 a[9] = {p[0], p[1], p[2]}, b[9];
                    if (!single) {
                        Bounds3 vb = grid.voxelBounds(voxel);
                        for (int k = 0; k < 3 && n >= 3; ++k) {
                            n = clip(a, n, b, k, vb.lower[k], 1.0f);
                            n = clip(b, n, a, k, vb.upper[k], -1.0f);
                        }
                    }
                    if (n < 3) continue;
                    float area = polygonArea(a, n);
                    if (!(area > 0.0f) || !std::isfinite(area)) continue;
                    piece.area = area;
                    piece.vertexCount = uint8_t(n);
                    for (int i = 0; i < n; ++i) piece.vertices[i] = a[i];
                    byVoxel_[voxel].push_back(uint32_t(pieces_.size()));
                    voxelArea_[voxel] += area;
                    totalArea_ += area;
                    pieces_.push_back(piece);
                }
    }
}

glm::vec3 SurfacePieces::samplePiece(const SurfacePiece& piece, glm::vec2 u, float& b1, float& b2) const {
    // Pick a fan triangle of the polygon by area (reusing u.x), then a uniform point in it.
    int fan = 0;
    if (piece.vertexCount > 3) {
        float target = u.x * piece.area, acc = 0.0f;
        int last = piece.vertexCount - 3;
        for (fan = 0; fan < last; ++fan) {
            const glm::vec3* v = piece.vertices;
            float a = 0.5f * glm::length(glm::cross(v[fan + 1] - v[0], v[fan + 2] - v[0]));
            if (acc + a > target) {
                u.x = a > 0.0f ? std::clamp((target - acc) / a, 0.0f, 0.99999994f) : 0.5f;
                break;
            }
            acc += a;
        }
        if (fan == last) {
            const glm::vec3* v = piece.vertices;
            float a = 0.5f * glm::length(glm::cross(v[fan + 1] - v[0], v[fan + 2] - v[0]));
            u.x = a > 0.0f ? std::clamp((target - acc) / a, 0.0f, 0.99999994f) : 0.5f;
        }
    }
    const glm::vec3& A = piece.vertices[0];
    const glm::vec3& B = piece.vertices[fan + 1];
    const glm::vec3& C = piece.vertices[fan + 2];
    float su = std::sqrt(u.x);
    float s1 = su * (1.0f - u.y), s2 = su * u.y;
    glm::vec3 p = (1.0f - s1 - s2) * A + s1 * B + s2 * C;
    // Barycentrics of p on the original triangle (least squares on its plane).
    const glm::uvec3& tri = mesh_.triangles[piece.triangle];
    glm::vec3 p0 = mesh_.positions[tri.x], e1 = mesh_.positions[tri.y] - p0, e2 = mesh_.positions[tri.z] - p0, d = p - p0;
    float d11 = glm::dot(e1, e1), d12 = glm::dot(e1, e2), d22 = glm::dot(e2, e2);
    float d1 = glm::dot(d, e1), d2 = glm::dot(d, e2);
    float det = d11 * d22 - d12 * d12;
    b1 = det != 0.0f ? (d22 * d1 - d12 * d2) / det : 1.0f / 3.0f;
    b2 = det != 0.0f ? (d11 * d2 - d12 * d1) / det : 1.0f / 3.0f;
    b1 = std::clamp(b1, 0.0f, 1.0f);
    b2 = std::clamp(b2, 0.0f, 1.0f - b1);
    return p;
}

}  // namespace nrad
