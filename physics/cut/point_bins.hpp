#pragma once
// Points binned in cubes over their box (compressed rows): the cutting code's searches by
// position (VolumeCutter's nearest integration point and its link boxes, the linked-across
// check's elements by their centres).

#include "physics/core/model.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstddef>
#include <vector>

namespace incise::physics {

// Cubes of side `cell` over the points' box, each bin's points by increasing index.
struct PointBins {
  Vec3 lo = Vec3::Zero(), hi = Vec3::Zero();
  double cell = 1;
  std::array<long long, 3> count{0, 0, 0};
  std::vector<int> start, items;
  std::vector<Vec3> item_points;  // per item, its point at the build

  // False (and nothing usable) when there is no point or one is not finite.
  bool build(const std::vector<Vec3>& points, double spacing) {
    if (points.empty()) return false;
    hi = points[0];
    lo = points[0];
    for (const Vec3& p : points) {
      if (!p.allFinite()) return false;
      lo = lo.cwiseMin(p), hi = hi.cwiseMax(p);
    }
    // About one point per bin; coarser when the points are spread out (never more bins than
    // 8 per point).
    cell = spacing;
    for (;;) {
      long long total = 1;
      for (int axis = 0; axis < 3; ++axis) {
        count[axis] = static_cast<long long>((hi[axis] - lo[axis]) / cell) + 1;
        total *= count[axis];
      }
      if (total <= 8 * static_cast<long long>(points.size()) + 64) break;
      cell *= 2;
    }
    start.assign(static_cast<std::size_t>(count[0] * count[1] * count[2]) + 1, 0);
    std::vector<long long> slot_of(points.size());
    for (std::size_t e = 0; e < points.size(); ++e) {
      const auto c = coordinates(points[e]);
      slot_of[e] = c[0] + count[0] * (c[1] + count[1] * c[2]);
      ++start[static_cast<std::size_t>(slot_of[e]) + 1];
    }
    for (std::size_t b = 1; b < start.size(); ++b) start[b] += start[b - 1];
    items.resize(points.size());
    std::vector<int> fill(start.begin(), start.end() - 1);
    for (std::size_t e = 0; e < points.size(); ++e)
      items[static_cast<std::size_t>(fill[static_cast<std::size_t>(slot_of[e])]++)] = static_cast<int>(e);
    item_points.resize(points.size());
    for (std::size_t s = 0; s < items.size(); ++s) item_points[s] = points[static_cast<std::size_t>(items[s])];
    return true;
  }
  // The bin holding x along an axis, clamped to the grid (formed as a double first, so that
  // a far or infinite x clamps too; NaN gives bin 0).
  long long cell_of(int axis, double x) const {
    const double c = std::floor((x - lo[axis]) / cell);
    return c >= 0 ? static_cast<long long>(std::min(c, static_cast<double>(count[axis] - 1))) : 0;
  }
  std::array<long long, 3> coordinates(const Vec3& p) const { return {cell_of(0, p[0]), cell_of(1, p[1]), cell_of(2, p[2])}; }
  // Calls visit(s) for every slot s (items[s], item_points[s]) of the bins over [lo, hi],
  // clamped to the grid; all of them along an axis where a bound is NaN.
  template <class Visit>
  void visit_box(const Vec3& box_lo, const Vec3& box_hi, Visit&& visit) const {
    std::array<long long, 3> first{}, last{};
    for (int axis = 0; axis < 3; ++axis) {
      if (std::isnan(box_lo[axis]) || std::isnan(box_hi[axis])) {
        first[axis] = 0, last[axis] = count[axis] - 1;
      } else {
        first[axis] = cell_of(axis, box_lo[axis]), last[axis] = cell_of(axis, box_hi[axis]);
      }
    }
    for (long long k = first[2]; k <= last[2]; ++k)
      for (long long j = first[1]; j <= last[1]; ++j)
        for (long long i = first[0]; i <= last[0]; ++i) {
          const std::size_t b = static_cast<std::size_t>(i + count[0] * (j + count[1] * k));
          for (int s = start[b]; s < start[b + 1]; ++s) visit(s);
        }
  }
};

}  // namespace incise::physics
