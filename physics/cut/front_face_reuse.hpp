// FrontSurface's cut face kept from one sample to the next (front_surface.hpp, "Cost"): the
// last sample's triangulation, what changed in the region since, and the triangulation that
// keeps what lies well behind the front.
#pragma once

#include "physics/core/model.hpp"
#include "physics/cut/triangulate_2d.hpp"

#include <array>
#include <cstddef>
#include <cstdint>
#include <limits>
#include <utility>
#include <vector>

namespace incise::physics::front {

// The last sample's cut face as triangulated, in (s, t): the region's points and boundary and
// the constrained Delaunay triangles (before the shared inner edges are split). The region's
// points are the boundary's (the ends of its edges: chords, outline, slits), then the
// lattice's, row by row, each row by increasing column.
using StKey = std::pair<double, double>;
inline StKey st_key(const Vec2& p) { return {p.x(), p.y()}; }

struct FaceCache {
  bool valid = false;
  PlanarRegion region;
  std::vector<std::array<int, 3>> triangles;
  std::vector<std::pair<StKey, int>> sorted;  // the boundary's points by (s, t), with their index
  int lattice_begin = 0;                      // the lattice's first point in region.points
  std::vector<int> row_start;                 // per lattice row r: its points from lattice_begin + row_start[r]
  std::vector<int> column;                    // per lattice point: its column
  // Per lattice point: its point on the sheet, once the cell of the sheet that holds it is
  // fixed (between two samples before the last: it no longer changes), else lifted_final 0.
  std::vector<Vec3> lifted;
  std::vector<std::uint8_t> lifted_final;
};

// The first `count` points by (s, t), each with its index.
std::vector<std::pair<StKey, int>> sorted_points(const std::vector<Vec2>& points, size_t count);

// What changed in the region since the last sample's (FaceCache): per old point its new
// index (-1: gone), points told apart by their exact (s, t), which the stroke computes the
// same way at every sample; and the lowest t of a point added or gone, or of an end of a
// boundary edge added or gone.
struct FaceChange {
  std::vector<int> to_new;
  double t_change = std::numeric_limits<double>::infinity();
  std::vector<std::array<int, 2>> sorted_boundary;  // the region's boundary, sorted
};

// What changed in the region's boundary since the last sample's (`cache`): its points matched
// by their exact (s, t) (`new_sorted`: the region's boundary points sorted), its edges
// compared; t_change is the lowest t of a point or edge end added or gone. Lattice points are
// matched afterwards, by row and column (Recompute::lay_lattice, front_lattice.cpp).
FaceChange boundary_change(const FaceCache& cache, const PlanarRegion& region, const std::vector<std::pair<StKey, int>>& new_sorted);

// triangulate_region(region), keeping what the last sample's triangulation (`cache`) has well
// behind the front. Between two samples the region changes only at and above some t (the
// lowest t of a point added or gone, or of an end of a boundary edge added or gone: the
// front, its new crossings, a crossing a fold cancelled): a last triangle whose circumcircle
// lies below that t keeps its corners, has no new point in its circle and no new boundary
// edge through it, and stays inside (the boundary's change is a closed chain above it), so it
// is a triangle of the new constrained Delaunay triangulation too (which is unique for points
// in general position: the cut face's lattice is moved off its cocircular spots). Only the
// rest is triangulated again, bounded by the kept triangles' edges. The result is the same
// as triangulate_region's, element for element (both sorted, each triangle from its smallest
// index). Falls back to the whole region when nothing is kept, the rest cannot be
// triangulated on its own, or `change` is null (no valid cache). `next` is what the cache
// keeps of this region (its sorted boundary points and its lattice's rows), for the next.
std::vector<std::array<int, 3>> triangulate_face(const PlanarRegion& region, FaceCache& cache, const FaceChange* change,
                                                 FaceCache&& next, double slack, int& kept_count);

}  // namespace incise::physics::front
