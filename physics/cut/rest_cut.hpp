// The cut in the rest configuration (seed 004 §2.3: every topology edit happens at rest): the
// blade's sweep mapped back to rest as triangles, binned for segment and proximity queries.
// The volume's agreement pass and the linked-across check ask it which links it crosses.
#pragma once

#include "physics/core/model.hpp"
#include "physics/cut/uniform_grid.hpp"

#include <array>
#include <optional>
#include <vector>

namespace incise::physics {

struct RestTriangle {
  Vec3 a = Vec3::Zero();
  Vec3 b = Vec3::Zero();
  Vec3 c = Vec3::Zero();
};

// The parameter along [p, q] where the segment crosses the triangle (closed), or nothing.
// Degenerate triangles are never crossed.
std::optional<double> segment_crosses_triangle(const Vec3& p, const Vec3& q, const RestTriangle& triangle);

// The cut surface in the rest configuration: triangles with their boxes, for segment tests.
class RestCut {
 public:
  // `cell`: the side of the hash grid the triangles are binned in (about the size of the
  // segments tested: an integration cube).
  explicit RestCut(double cell = 0.005) : cell_(cell) {}
  void add(const RestTriangle& triangle);
  int size() const { return static_cast<int>(triangles_.size()); }
  const std::vector<RestTriangle>& triangles() const { return triangles_; }
  // True if [p, q] crosses any triangle (any of those added at or after index `from`).
  bool crosses(const Vec3& p, const Vec3& q, int from = 0) const;
  // The nearest point on the cut to p within `reach`, or nothing.
  std::optional<Vec3> nearest_point(const Vec3& p, double reach) const;
  // Whether anything lies within `reach` of the box [lo, hi].
  bool near_box(const Vec3& lo, const Vec3& hi, double reach) const;

 private:
  template <typename Visit>
  void for_each_near(const Vec3& lo, const Vec3& hi, double reach, const Visit& visit) const;

  double cell_;
  std::vector<RestTriangle> triangles_;
  std::vector<std::array<Vec3, 2>> boxes_;
  std::array<Vec3, 2> bounds_{Vec3::Zero(), Vec3::Zero()};  // the box of every triangle
  // The triangles binned in cells of side cell_ (on the lattice from the origin, coarser for a
  // cut spread wide) over their box with a margin; a triangle added later goes into the grid
  // as it is when it lies in it, else (or once many were added so) the grid is binned again
  // at the next query (a cut event adds its triangles, then asks many questions). A triangle
  // over more than 256 cells along an axis (a blade far larger than the body) is kept apart,
  // tested by every query. Queries are thus not safe to run concurrently.
  bool apart(int triangle) const;
  void bin() const;
  mutable UniformGrid grid_;
  mutable int binned_ = 0;  // the triangles in grid_
};

}  // namespace incise::physics
