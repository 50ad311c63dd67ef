// Moves the boundary nodes of a voxel tetrahedral mesh onto the surface it approximates, so
// that a body built from cells of side h shows its smooth shape instead of staircases of
// height h. Only the rest shape changes; no node or element is added or removed.
#pragma once

#include "physics/fem/tet_mesh.hpp"

#include <Eigen/Geometry>

#include <functional>

namespace incise::physics {

struct SnapReport {
  int boundary_nodes = 0;
  int moved = 0;         // moved the whole way to the surface
  int moved_partly = 0;  // stopped short so that no element got too flat
  int left = 0;          // no surface crossing within reach along the normal
  double min_volume_ratio = 1;  // smallest element volume after / before, over moved elements
};

// For each boundary node (in index order), finds where the line along its outward normal
// crosses the surface of `inside` within `reach` (bisection to reach / 2^bisections) and moves
// the node there, or part of the way (1/2, 1/4) when a full move would leave an adjacent
// element with less than `min_volume_ratio` of its voxel volume. Deterministic.
SnapReport snap_boundary_to_surface(TetMesh& mesh, const std::function<bool(const Vec3&)>& inside,
                                    double reach, double min_volume_ratio = 0.25,
                                    int bisections = 12);

}  // namespace incise::physics
