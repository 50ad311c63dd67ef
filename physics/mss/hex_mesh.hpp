// Hexahedral (brick) meshes for the Baudet / Fléchon mass-spring model (seed 003).
//
// Local node order (Fléchon Fig. 7, the generator fixes it so the spring layout is
// deterministic): bottom face 0-1-2-3, top face 4-5-6-7, node i + 4 above node i, with
// 0 = (x-, y-, z-), 1 = (x+, y-, z-), 2 = (x+, y+, z-), 3 = (x-, y+, z-).
#pragma once

#include "physics/core/model.hpp"

#include <array>
#include <functional>
#include <vector>

namespace incise::physics {

struct HexMesh {
  Vector rest;                              // 3n
  std::vector<std::array<int, 8>> hexes;    // node indices in the local order above
};

// The box [min, max] split into cells[0] x cells[1] x cells[2] equal bricks.
HexMesh make_box_hexes(Vec3 min, Vec3 max, std::array<int, 3> cells);

// The voxels of a grid over [min, max] (cells of about `resolution`, as many per axis as
// ceil(extent / resolution)) whose centre is inside; the nodes no voxel uses are dropped.
// A staircase of whole bricks: Baudet's formulas hold on bricks only, so the boundary is not
// snapped onto the shape.
HexMesh make_hexes_inside(const std::function<bool(const Vec3&)>& inside, Vec3 min, Vec3 max, double resolution);

// Volume of hexahedron `hex` at positions x, as Fléchon (§5.3) computes it: 5 tetrahedra.
double hex_volume(const Vector& x, const std::array<int, 8>& hex);

// The brick's edge lengths along its local x (0-1), y (0-3) and z (0-4) axes, each the mean
// of its four parallel edges.
Vec3 hex_edge_lengths(const Vector& x, const std::array<int, 8>& hex);

// The faces no other hexahedron shares, as outward triangles (two per face).
std::vector<std::array<int, 3>> hex_boundary_triangles(const std::vector<std::array<int, 8>>& hexes);

// The 12 edges of the local order, grouped by axis: [0, 4) along x, [4, 8) y, [8, 12) z.
extern const std::array<std::array<int, 2>, 12> kHexEdges;
// The 4 body diagonals (0,6), (1,7), (2,4), (3,5) (Fléchon Fig. 7).
extern const std::array<std::array<int, 2>, 4> kHexDiagonals;

}  // namespace incise::physics
