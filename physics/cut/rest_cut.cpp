#include "physics/cut/rest_cut.hpp"

#include "physics/core/contact.hpp"

#include <Eigen/Geometry>

#include <algorithm>
#include <array>
#include <cmath>
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

const std::vector<int>* RestCut::bin(long long i, long long j, long long k) const {
  i -= bins_lo_[0], j -= bins_lo_[1], k -= bins_lo_[2];
  if (i < 0 || j < 0 || k < 0 || i >= bins_count_[0] || j >= bins_count_[1] || k >= bins_count_[2]) return nullptr;
  return &bins_[static_cast<size_t>(i + bins_count_[0] * (j + bins_count_[1] * k))];
}

std::vector<int>* RestCut::bin(long long i, long long j, long long k) {
  return const_cast<std::vector<int>*>(std::as_const(*this).bin(i, j, k));
}

void RestCut::cover(const std::array<long long, 3>& first, const std::array<long long, 3>& last) {
  bool inside = !bins_.empty();
  for (int axis = 0; axis < 3; ++axis)
    inside = inside && first[axis] >= bins_lo_[axis] && last[axis] < bins_lo_[axis] + bins_count_[axis];
  if (inside) return;
  // Grow to the union, with as much again as margin on each side that grew (amortised).
  std::array<long long, 3> lo{}, count{};
  for (int axis = 0; axis < 3; ++axis) {
    long long new_lo = first[axis], new_hi = last[axis];
    if (!bins_.empty()) {
      new_lo = std::min(new_lo, bins_lo_[axis]);
      new_hi = std::max(new_hi, bins_lo_[axis] + bins_count_[axis] - 1);
    }
    const long long margin = (new_hi - new_lo + 1) / 2 + 1;
    if (bins_.empty() || new_lo < bins_lo_[axis]) new_lo -= margin;
    if (bins_.empty() || new_hi >= bins_lo_[axis] + bins_count_[axis]) new_hi += margin;
    lo[axis] = new_lo;
    count[axis] = new_hi - new_lo + 1;
  }
  std::vector<std::vector<int>> grown(static_cast<size_t>(count[0] * count[1] * count[2]));
  for (long long k = 0; k < bins_count_[2]; ++k)
    for (long long j = 0; j < bins_count_[1]; ++j)
      for (long long i = 0; i < bins_count_[0]; ++i) {
        auto& from = bins_[static_cast<size_t>(i + bins_count_[0] * (j + bins_count_[1] * k))];
        if (from.empty()) continue;
        const long long gi = i + bins_lo_[0] - lo[0], gj = j + bins_lo_[1] - lo[1], gk = k + bins_lo_[2] - lo[2];
        grown[static_cast<size_t>(gi + count[0] * (gj + count[1] * gk))] = std::move(from);
      }
  bins_ = std::move(grown);
  bins_lo_ = lo;
  bins_count_ = count;
}

template <typename Visit>
void RestCut::for_each_near(const Vec3& lo, const Vec3& hi, double reach, const Visit& visit) const {
  if (triangles_.empty()) return;
  ++query_;
  std::array<long long, 3> first{}, last{};
  for (int axis = 0; axis < 3; ++axis) {
    // Only the bins that exist: clamped to the covered range (none outside it holds anything).
    first[axis] = std::max(bins_lo_[axis], static_cast<long long>(std::floor((lo[axis] - reach) / cell_)));
    last[axis] = std::min(bins_lo_[axis] + bins_count_[axis] - 1,
                          static_cast<long long>(std::floor((hi[axis] + reach) / cell_)));
    if (last[axis] < first[axis]) return;
  }
  // A query box much larger than the cut: scan the triangles instead of the cells.
  const double cells = static_cast<double>(last[0] - first[0] + 1) * (last[1] - first[1] + 1) * (last[2] - first[2] + 1);
  if (cells > 4.0 * static_cast<double>(triangles_.size())) {
    for (size_t t = 0; t < triangles_.size(); ++t)
      if (boxes_overlap(lo, hi, boxes_[t][0], boxes_[t][1], reach) && visit(static_cast<int>(t))) return;
    return;
  }
  for (long long k = first[2]; k <= last[2]; ++k)
    for (long long j = first[1]; j <= last[1]; ++j)
      for (long long i = first[0]; i <= last[0]; ++i) {
        for (int t : *bin(i, j, k)) {
          if (stamp_[t] == query_) continue;
          stamp_[t] = query_;
          if (boxes_overlap(lo, hi, boxes_[t][0], boxes_[t][1], reach) && visit(t)) return;
        }
      }
}

void RestCut::add(const RestTriangle& triangle) {
  const int index = static_cast<int>(triangles_.size());
  triangles_.push_back(triangle);
  const auto box = box_of(triangle);
  boxes_.push_back(box);
  stamp_.push_back(0);
  std::array<long long, 3> first{}, last{};
  for (int axis = 0; axis < 3; ++axis) {
    first[axis] = static_cast<long long>(std::floor(box[0][axis] / cell_));
    last[axis] = static_cast<long long>(std::floor(box[1][axis] / cell_));
    // A huge triangle (a blade far larger than the body) is clipped to a bounded bin range;
    // the triangle still gets its box test, so nothing is lost but speed.
    last[axis] = std::min(last[axis], first[axis] + 256);
  }
  cover(first, last);
  for (long long k = first[2]; k <= last[2]; ++k)
    for (long long j = first[1]; j <= last[1]; ++j)
      for (long long i = first[0]; i <= last[0]; ++i) bin(i, j, k)->push_back(index);
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
