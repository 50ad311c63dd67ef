// Tetrahedral meshes and their generators.
//
// Tetrahedra are positively oriented: det[X1 - X0, X2 - X0, X3 - X0] > 0.
#pragma once

#include <array>
#include <cstdint>
#include <functional>
#include <vector>

#include "physics/core/model.hpp"

namespace incise::physics {

struct TetMesh {
  Vector rest;                           // 3n
  std::vector<std::array<int, 4>> tets;  // node indices
};

// 10-node tetrahedra. Node order: the 4 corners 0..3, then the edge midpoints of the edges
// (0,1), (1,2), (2,0), (0,3), (1,3), (2,3) as nodes 4..9. Edges are straight: a midpoint node
// sits at the middle of its edge.
struct QuadraticTetMesh {
  Vector rest;                            // 3n
  std::vector<std::array<int, 10>> tets;  // node indices
};

// Corners (a, b) of the edge whose midpoint is node 4 + e of a 10-node tetrahedron.
inline constexpr std::array<std::array<int, 2>, 6> quadratic_tet_edges{
    {{0, 1}, {1, 2}, {2, 0}, {0, 3}, {1, 3}, {2, 3}}};

// Regular grid of cells[0] x cells[1] x cells[2] hexahedra, each split into 6 tetrahedra
// around its main diagonal (Kuhn / Freudenthal split; every cell uses the same diagonal, so
// the mesh is conforming). Node (i, j, k) has index i + (cells[0] + 1) (j + (cells[1] + 1) k);
// the 6 tets of cell (i, j, k) follow one another, cells ordered x fastest.
TetMesh make_box_tets(Vec3 min, Vec3 max, std::array<int, 3> cells);

// The same split with 10-node tetrahedra. Every edge midpoint, face-diagonal midpoint and
// cell centre is a node of the grid with twice the resolution, so the nodes are exactly that
// grid: node (i, j, k), 0 <= i <= 2 cells[0], has index i + (2 cells[0] + 1)(j + (2 cells[1] + 1)
// k).
QuadraticTetMesh make_box_quadratic_tets(Vec3 min, Vec3 max, std::array<int, 3> cells);

// Voxelises [min, max] with ceil(extent / cell_size) cells per axis (spacing extent / count,
// so at most cell_size) and keeps the cells whose centre is inside; each becomes 6 tets as in
// make_box_tets. Unreferenced grid nodes are removed, the others keep their grid order.
// Throws std::invalid_argument if cell_size <= 0, the box is empty, or no cell is inside.
TetMesh make_tets_inside(const std::function<bool(const Vec3&)>& inside, Vec3 min, Vec3 max,
                         double cell_size);

// Faces used by exactly one tetrahedron, counter-clockwise seen from outside (outward normal
// (b - a) x (c - a)), assuming positively oriented tets. Order: by tet index, then by the face
// opposite corner 0, 1, 2, 3.
std::vector<std::array<int, 3>> boundary_triangles(const std::vector<std::array<int, 4>>& tets);

// 1 for nodes with min <= X <= max componentwise (bounds included), else 0.
std::vector<uint8_t> nodes_in_box(const Vector& rest, Vec3 min, Vec3 max);

// Sum of the signed volumes of the tetrahedra.
double total_volume(const Vector& rest, const std::vector<std::array<int, 4>>& tets);

}  // namespace incise::physics
