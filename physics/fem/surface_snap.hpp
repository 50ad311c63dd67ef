// Moves the boundary nodes of a voxel tetrahedral mesh onto the surface it approximates, so
// that a body built from cells of side h shows its smooth shape instead of staircases of
// height h. Only the rest shape changes; no node or element is added or removed.
#pragma once

#include "physics/fem/tet_mesh.hpp"

#include <Eigen/Geometry>

#include <array>
#include <functional>
#include <optional>
#include <utility>
#include <vector>

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

struct FairReport {
  int vertices = 0;     // on a triangle (the others are left alone)
  int projected = 0;     // put on the boundary (along their normal, or from their one-ring's centroid)
  int not_found = 0;     // no boundary crossing within reach: left where they were
  int off_shape = 0;     // a crossing found, but every move onto it would turn a triangle over
  int creases = 0;       // on a crease or corner of the shape: projected, never slid
  int slid = 0;          // tangential moves taken, over every pass
  int refused = 0;       // tangential moves refused (no crossing, or a triangle would turn over)
};

// A shape's boundary along a line p + s n, for shapes that know it exactly (an imported mesh:
// engine/mesh_shape.hpp): the winding number at p and, sorted, the parameters s where the line
// crosses the boundary with the change of the winding number there going towards +s. Inside
// is a winding number above one half, as the point test has it.
struct LineSection {
  int winding = 0;
  std::vector<std::pair<double, int>> crossings;
  bool inside_at(double s) const;
};
// The line p + s n, |s| <= reach, or nullopt where the shape cannot say (the line grazes an
// edge): the caller asks point by point.
using LineQuery = std::function<std::optional<LineSection>(const Vec3& p, const Vec3& n, double reach)>;

// Fairs a closed triangle surface that approximates the boundary of `inside` (a voxel
// boundary snapped by snap_boundary_to_surface, whose nodes stop short or land unevenly where
// the voxel normals are quantised: the organ's hammered look). Every vertex is put on the
// boundary along its angle-weighted normal (bisection, within 1.5 cell), or, where that
// would turn one of its triangles over (the tip of a bump), from its one-ring's centroid; then, `passes`
// times in index order, each vertex away from a crease slides towards the centroid of its
// one-ring within its tangent plane and is put back on the boundary, unless that would turn
// one of its triangles over. A vertex is on a crease when the boundary, followed along the
// normal half a cell away from it in any of eight tangent directions, lies more than an
// eighth of a cell from its tangent plane (a smooth boundary's radius of curvature would
// have to be under a cell): box edges and corners, a flat base's rim. Only positions
// change; the triangles are the same. Deterministic. For surfaces carried by no element (an
// embedded surface): the tetrahedra a snap keeps from flattening are not looked at.
// Throws std::invalid_argument (naming it) for a cell that is not positive, negative passes,
// a triangle's vertex out of range or a vertex on a triangle that is not finite, before
// anything moves. With `along`, each march and bisection along a line classifies its points
// from the line's section rather than asking `inside` for each (the same answers, but for
// points within rounding of the boundary).
FairReport fair_surface_onto_shape(std::vector<Vec3>& vertices, const std::vector<std::array<int, 3>>& triangles,
                                   const std::function<bool(const Vec3&)>& inside, double cell, int passes = 3,
                                   const LineQuery& along = {});

}  // namespace incise::physics
