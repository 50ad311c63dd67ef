// FrontSurface's edge table (front_surface.hpp): every edge of its base mesh once, with the
// triangles on each side; building it checks that the mesh is closed and consistently oriented.
#pragma once

#include <array>
#include <vector>

namespace incise::physics::front {

// Each undirected edge of a closed mesh, with the triangle on each side.
struct EdgeTable {
  std::vector<std::array<int, 2>> ends;          // lower id first
  std::vector<std::array<int, 2>> triangles;     // the two triangles using the edge
  std::vector<std::array<int, 3>> of_triangle;   // edge k of triangle (t[k], t[k+1])
};

// Throws std::invalid_argument naming the first edge not used exactly once in each direction.
EdgeTable edge_table(const std::vector<std::array<int, 3>>& triangles);

}  // namespace incise::physics::front
