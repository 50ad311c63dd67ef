// A uniform grid over a surface's triangles' bounding boxes, built from the current positions
// (the surface moves every step, so it is rebuilt per call: one pass over the triangles), for
// nearest-triangle queries: mark_engaged and held_contact test each query point against the
// triangles near it instead of every triangle of the surface.
//
// The callers keep their scan's rule (a triangle replaces the nearest so far when it is
// strictly nearer, skipped when its box is no nearer) and only shorten the list it runs over:
// candidates() returns, in increasing triangle order, every used triangle whose box is within
// the nearest triangle's distance (plus a relative and an absolute margin far above rounding)
// of the point. The triangles left out are farther than the nearest by more than rounding can
// bridge, so they can never be the nearest nor hide it: the scan ends with the same triangle
// and the same distance, bit for bit, as over the whole surface.
#pragma once

#include "physics/core/model.hpp"

#include <array>
#include <cstdint>
#include <vector>

namespace incise::physics {

class TriangleGrid {
 public:
  // use[t] false leaves triangle t out (a cut face, a degenerate one: those the scan skips).
  TriangleGrid(const Vector& x, const std::vector<std::array<int, 3>>& surface, const std::vector<std::uint8_t>& use);

  // The triangles to scan for p's nearest, in increasing order (all used ones where the
  // positions or p are not finite).
  void candidates(const Vec3& p, std::vector<int>& out);

  const Vec3& lo(int t) const { return lo_[static_cast<std::size_t>(t)]; }
  const Vec3& hi(int t) const { return hi_[static_cast<std::size_t>(t)]; }

 private:
  double distance(const Vec3& p, int t) const;
  void all(std::vector<int>& out) const;

  const Vector& x_;
  const std::vector<std::array<int, 3>>& surface_;
  std::vector<int> used_;       // the used triangles, in order
  std::vector<Vec3> lo_, hi_;   // per triangle (used ones)
  bool finite_ = true;
  Vec3 origin_ = Vec3::Zero();
  double cell_ = 0, slack_ = 0;  // cell size; the absolute margin
  std::array<int, 3> dims_{0, 0, 0};
  std::vector<int> start_, items_;  // cell c's triangles: items_[start_[c] .. start_[c + 1]), in order
  std::vector<int> stamp_;          // per triangle: the query that last saw it
  std::vector<double> seen_;        // per triangle: its distance in that query (-1: not computed)
  int query_ = 0;
};

}  // namespace incise::physics
