// A uniform grid over some of a surface's triangles' bounding boxes, built from the current
// positions (the surface moves every step, so it is rebuilt per call), for nearest-triangle
// queries: mark_engaged and held_contact (through nearest_triangles) test each query point
// against the triangles near it instead of every triangle of the surface.
//
// The grid holds the triangles it is given, each in a slot (slots in increasing triangle
// order). The callers keep their scan's rule (a triangle replaces the nearest so far when it is
// strictly nearer, skipped when its box is no nearer) and only shorten the list it runs over:
// candidates() returns, in increasing order, the slot of every triangle whose box is within
// the nearest triangle's distance (plus a relative and an absolute margin far above rounding)
// of the point. The triangles left out are farther than the nearest by more than rounding can
// bridge, so they can never be the nearest nor hide it: the scan ends with the same triangle
// and the same distance, bit for bit, as over all the grid's triangles.
#pragma once

#include "physics/core/model.hpp"

#include <array>
#include <cstdint>
#include <vector>

namespace incise::physics {

class TriangleGrid {
 public:
  // Over the used triangles: use[t] false leaves triangle t out (a cut face, a degenerate
  // one: those the scan skips); triangles past the end of `use` are used.
  TriangleGrid(const Vector& x, const std::vector<std::array<int, 3>>& surface, const std::vector<std::uint8_t>& use);
  // Over `triangles` (indices into surface, increasing).
  TriangleGrid(const Vector& x, const std::vector<std::array<int, 3>>& surface, std::vector<int> triangles);

  // A query's bookkeeping (per slot: the query that last saw it, its distance there): one per
  // thread that queries the grid at once.
  struct Scratch {
    std::vector<int> stamp;
    std::vector<double> seen;  // -1: not computed
    int query = 0;
  };

  // The slots to scan for p's nearest, in increasing order (every slot where the positions or
  // p are not finite). The scratch is the caller's, so threads may query one grid side by side.
  void candidates(const Vec3& p, std::vector<int>& out, Scratch& scratch) const;

  int size() const { return static_cast<int>(used_.size()); }
  int triangle(int slot) const { return used_[static_cast<std::size_t>(slot)]; }
  // The box of the slot's triangle.
  const Vec3& lo(int slot) const { return lo_[static_cast<std::size_t>(slot)]; }
  const Vec3& hi(int slot) const { return hi_[static_cast<std::size_t>(slot)]; }

 private:
  void build();
  double distance(const Vec3& p, int slot) const;
  void all(std::vector<int>& out) const;

  const Vector& x_;
  const std::vector<std::array<int, 3>>& surface_;
  std::vector<int> used_;       // per slot: its triangle, increasing
  std::vector<Vec3> lo_, hi_;   // per slot
  bool finite_ = true;
  Vec3 origin_ = Vec3::Zero();
  double cell_ = 0, slack_ = 0;  // cell size; the absolute margin
  std::array<int, 3> dims_{0, 0, 0};
  std::vector<int> start_, items_;  // cell c's slots: items_[start_[c] .. start_[c + 1]), in order
};

}  // namespace incise::physics
