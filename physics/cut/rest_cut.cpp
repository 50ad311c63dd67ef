#include "physics/cut/rest_cut.hpp"

#include "physics/core/contact.hpp"

#include <Eigen/Geometry>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <limits>
#include <optional>
#include <utility>
#include <vector>

namespace incise::physics {

namespace {

std::array<Vec3, 2> box_of(const RestTriangle& t) {
  return {t.a.cwiseMin(t.b).cwiseMin(t.c), t.a.cwiseMax(t.b).cwiseMax(t.c)};
}

bool boxes_overlap(const Vec3& lo_a, const Vec3& hi_a, const Vec3& lo_b, const Vec3& hi_b, double reach) {
  for (int axis = 0; axis < 3; ++axis) {
    if (lo_a[axis] > hi_b[axis] + reach || lo_b[axis] > hi_a[axis] + reach) return false;
  }
  return true;
}


}  // namespace

std::optional<double> segment_crosses_triangle(const Vec3& p, const Vec3& q, const RestTriangle& t) {
  // Moller-Trumbore on the closed triangle and the closed segment.
  const Vec3 direction = q - p;
  const Vec3 edge_1 = t.b - t.a, edge_2 = t.c - t.a;
  const Vec3 h = direction.cross(edge_2);
  const double determinant = edge_1.dot(h);
  const double scale = edge_1.norm() * edge_2.norm() * direction.norm();
  if (!(scale > 0) || std::abs(determinant) <= 1e-12 * scale) return std::nullopt;  // parallel or degenerate
  const double inverse = 1.0 / determinant;
  const Vec3 s = p - t.a;
  const double u = inverse * s.dot(h);
  if (u < 0 || u > 1) return std::nullopt;
  const Vec3 k = s.cross(edge_1);
  const double v = inverse * direction.dot(k);
  if (v < 0 || u + v > 1) return std::nullopt;
  const double along = inverse * edge_2.dot(k);
  if (along < 0 || along > 1) return std::nullopt;
  return along;
}

bool RestCut::apart(int t) const {
  GridCells lattice;
  lattice.cell = cell_;
  for (int axis = 0; axis < 3; ++axis)
    if (!(lattice.lattice(axis, boxes_[static_cast<size_t>(t)][1][axis]) - lattice.lattice(axis, boxes_[static_cast<size_t>(t)][0][axis]) <= 256))
      return true;
  return false;
}

void RestCut::bin() const {
  // The box of the triangles binned, with half its extent again on each side (and a cell):
  // a cut growing from there is added to the grid as it grows, not binned again.
  Vec3 lo = Vec3::Constant(std::numeric_limits<double>::infinity()), hi = -lo;
  for (int t = 0; t < size(); ++t)
    if (!apart(t)) lo = lo.cwiseMin(boxes_[static_cast<size_t>(t)][0]), hi = hi.cwiseMax(boxes_[static_cast<size_t>(t)][1]);
  GridCells frame;
  if (lo[0] <= hi[0]) {
    const Vec3 margin = 0.5 * (hi - lo) + Vec3::Constant(cell_);
    frame = GridCells::fit(Vec3::Zero(), lo - margin, hi + margin, cell_, 1 << 22);
  }
  grid_.build(frame, size(), [&](int t, GridCell& first, GridCell& last) {
    if (apart(t)) return 2;
    frame.range(boxes_[static_cast<size_t>(t)][0], boxes_[static_cast<size_t>(t)][1], first, last);
    return 1;
  });
  binned_ = size();
}

template <typename Visit>
void RestCut::for_each_near(const Vec3& lo, const Vec3& hi, double reach, const Visit& visit) const {
  // Nothing near a query that misses the box of every triangle (most links are far from the cut).
  if (triangles_.empty() || !boxes_overlap(lo, hi, bounds_[0], bounds_[1], reach)) return;
  if (binned_ != size()) bin();
  const GridCells& cells = grid_.cells;
  // A query box much larger than the cut: scan the triangles instead of the cells.
  GridCell first{}, last{};
  cells.range(lo - Vec3::Constant(reach), hi + Vec3::Constant(reach), first, last);
  const double count = static_cast<double>(last[0] - first[0] + 1) * static_cast<double>(last[1] - first[1] + 1) *
                       static_cast<double>(last[2] - first[2] + 1);
  // Every triangle whose box meets the query's grown by reach (the answers below are the same
  // whatever the order: any crossing, the nearest with ties to the lower index, any near).
  bool done = false;
  const auto test = [&](int t) {
    if (!done && boxes_overlap(lo, hi, boxes_[static_cast<size_t>(t)][0], boxes_[static_cast<size_t>(t)][1], reach)) done = visit(t);
  };
  if (cells.total() == 0 || count > 4.0 * static_cast<double>(triangles_.size())) {
    for (int t = 0; t < size() && !done; ++t) test(t);
    return;
  }
  grid_.visit_box_once(lo - Vec3::Constant(reach), hi + Vec3::Constant(reach), test);
}

void RestCut::add(const RestTriangle& triangle) {
  const int t = size();
  triangles_.push_back(triangle);
  boxes_.push_back(box_of(triangle));
  bounds_ = t == 0 ? boxes_.back() : std::array<Vec3, 2>{bounds_[0].cwiseMin(boxes_.back()[0]), bounds_[1].cwiseMax(boxes_.back()[1])};
  if (binned_ != t || grid_.added() > grid_.slots() / 4 + 64) return;  // binned again at the next query
  // Into the grid as it is, when its cells lie in it.
  if (apart(t)) {
    grid_.add(t, {}, {}, true);
    binned_ = size();
    return;
  }
  const GridCells& cells = grid_.cells;
  const GridCell first = cells.unclamped_cell_of(boxes_.back()[0]), last = cells.unclamped_cell_of(boxes_.back()[1]);
  if (cells.total() == 0 || !cells.inside(first[0], first[1], first[2]) || !cells.inside(last[0], last[1], last[2])) return;
  grid_.add(t, first, last);
  binned_ = size();
}

bool RestCut::crosses(const Vec3& p, const Vec3& q, int from) const {
  if (from >= size()) return false;
  bool crossed = false;
  for_each_near(p.cwiseMin(q), p.cwiseMax(q), 0, [&](int t) {
    crossed = t >= from && segment_crosses_triangle(p, q, triangles_[t]).has_value();
    return crossed;
  });
  return crossed;
}

std::optional<Vec3> RestCut::nearest_point(const Vec3& p, double reach) const {
  std::optional<Vec3> best;
  double best_distance = reach;
  int best_index = -1;
  for_each_near(p, p, reach, [&](int t) {
    const Vec3 closest = closest_point_on_triangle(p, triangles_[t].a, triangles_[t].b, triangles_[t].c);
    const double distance = (closest - p).norm();
    // Ties to the lower index, so the result does not depend on the bins' order.
    if (distance < best_distance || (distance == best_distance && best_index >= 0 && t < best_index)) {
      best_distance = distance;
      best = closest;
      best_index = t;
    }
    return false;
  });
  return best;
}

bool RestCut::near_box(const Vec3& lo, const Vec3& hi, double reach) const {
  bool near = false;
  for_each_near(lo, hi, reach, [&](int) { return near = true; });
  return near;
}

}  // namespace incise::physics
