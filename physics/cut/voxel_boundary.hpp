// The first surface of a cuttable body: the boundary of a voxel fill (cubes of side `cell`,
// finer than the integration grid as seed 004 §5.3 requires), its outer nodes snapped onto
// the true surface. The front surface (front_surface.hpp) then cuts it; nothing here cuts.
//
// Where two cubes touch along an edge only (a pinch: four triangles on one edge), the empty
// cube between them is filled, so the boundary is a closed 2-manifold. Each grid node gets one
// vertex per group of its inside cubes joined through shared faces; the vertices are numbered
// as the faces meet them, cube by cube in increasing index.
#pragma once

#include "physics/core/model.hpp"

#include <array>
#include <functional>
#include <vector>

namespace incise::physics {

struct TriangleSurface {
  std::vector<Vec3> vertices;
  std::vector<std::array<int, 3>> triangles;
};

// The body {inside} within [lo, hi]. Throws std::invalid_argument if the cell is not positive,
// the box holds more than 4096 cells along an axis, or no cube centre is inside.
TriangleSurface voxel_boundary(const std::function<bool(const Vec3&)>& inside, Vec3 lo, Vec3 hi, double cell);

}  // namespace incise::physics
