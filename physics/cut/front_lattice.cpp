// Recompute's lattice: the cut face's fixed vertices, rows kept from the last sample where
// its boundary has not changed (front_recompute.hpp).
#include "physics/cut/front_recompute.hpp"

#include "physics/core/mix.hpp"
#include <algorithm>
#include <cmath>
#include <cstdint>

namespace incise::physics {

using namespace front;

// Fixed vertices: a triangular lattice of spacing w in (s, t), kept away from the boundary.
// First what changed since the last sample's region (FaceCache), for triangulate_face: the
// boundary's points matched by their exact (s, t) and its edges compared. The boundary
// changes only at and above t_boundary; a lattice row lower than that by more than the gap
// (and the jitter, in lay_lattice) sees the same boundary edges near it and across it, so it
// comes out as it was: it is taken from the last sample's instead of being made again.
void FrontSurface::Recompute::match_last_face() {
  row = w * std::sqrt(3.0) / 2;
  gap = 0.45 * w;
  extent = Vec2(surface.blade_s_.back(), surface.sample_t_.back());
  const size_t boundary_points = region.points.size();
  next.lattice_begin = static_cast<int>(boundary_points);
  next.sorted = sorted_points(region.points, boundary_points);
  incremental = surface.reuse_face_ && cache.valid;
  if (incremental) change = boundary_change(cache, region, next.sorted);
  t_boundary = change.t_change;  // infinite when not incremental
}

double FrontSurface::Recompute::distance_to_segment(const Vec2& p, const Vec2& a, const Vec2& b) {
  const Vec2 d = b - a;
  const double length_squared = d.squaredNorm();
  const double f = length_squared > 0 ? std::clamp((p - a).dot(d) / length_squared, 0.0, 1.0) : 0.0;
  return (p - (a + f * d)).norm();
}

// Rows taken whole from the last sample's lattice: below t_boundary by the gap and the jitter
// (a thousandth of w) with room. The rows made again are those from r_first on: only they
// look at the boundary's edges (binned here) and at where it crosses them.
void FrontSurface::Recompute::bin_boundary() {
  old_rows = incremental ? static_cast<int>(cache.row_start.size()) - 1 : 0;
  const auto row_taken = [&](int r) { return r < old_rows && r * row + gap + 2e-3 * w < t_boundary; };
  r_first = 1;
  while (row_taken(r_first)) ++r_first;
  // The boundary's edges binned in cells of side w over the (s, t) rectangle (the cells below
  // the lowest one a point of row r_first falls in are never looked at: left empty).
  const int columns = std::max(1, static_cast<int>(std::ceil(extent.x() / w))), rows = std::max(1, static_cast<int>(std::ceil(extent.y() / w)));
  // One layer of cells, (s, t) as (x, y).
  frame.cell = w;
  frame.count = {columns, rows, 1};
  const int lowest_cell_row = static_cast<int>(frame.cell_of(1, r_first * row));
  boundary_cells.build(frame, static_cast<int>(region.boundary.size()), [&](int e, GridCell& from, GridCell& to) {
    const Vec2& a = region.points[static_cast<size_t>(region.boundary[static_cast<size_t>(e)][0])];
    const Vec2& b = region.points[static_cast<size_t>(region.boundary[static_cast<size_t>(e)][1])];
    frame.range(Vec3(std::min(a.x(), b.x()) - gap, std::min(a.y(), b.y()) - gap, 0),
                Vec3(std::max(a.x(), b.x()) + gap, std::max(a.y(), b.y()) + gap, 0), from, to);
    from[1] = std::max<long long>(from[1], lowest_cell_row);
    return true;
  });
  // Per lattice row, where the boundary crosses it (s, and +1 going up in t, -1 going down;
  // each edge taken half-open, from its lower end): a point is inside the region when the
  // crossings on its right wind round it (the region is on the edges' left). The points
  // outside (where the blade's sheet is outside the body) would only be triangulated away.
  row_crossings.resize(static_cast<size_t>(std::floor(extent.y() / row)) + 2);
  for (const auto& edge : region.boundary) {
    const Vec2& a = region.points[static_cast<size_t>(edge[0])];
    const Vec2& b = region.points[static_cast<size_t>(edge[1])];
    if (a.y() == b.y()) continue;
    const Vec2& low = a.y() < b.y() ? a : b;
    const Vec2& high = a.y() < b.y() ? b : a;
    for (int r = std::max(r_first, static_cast<int>(std::ceil(low.y() / row))); r < static_cast<int>(row_crossings.size()) && r * row < high.y(); ++r) {
      if (r * row < low.y()) continue;
      const double f = (r * row - low.y()) / (high.y() - low.y());
      row_crossings[static_cast<size_t>(r)].emplace_back(low.x() + f * (high.x() - low.x()), a.y() < b.y() ? 1 : -1);
    }
  }
}

// The lattice's points, row by row: rows below r_first copied from the last sample's, the
// others made inside the region and away from its boundary, each matched with the last
// sample's point of its row and column (change.to_new; change.t_change lowered where one is
// added or gone).
void FrontSurface::Recompute::lay_lattice() {
  next.row_start.assign(2, 0);  // rows 0 (empty) and, below, 1, 2, ...
  for (int r = 1; r * row < extent.y(); ++r) {
    const int old_first = r < old_rows ? cache.row_start[static_cast<size_t>(r)] : 0;
    const int old_last = r < old_rows ? cache.row_start[static_cast<size_t>(r) + 1] : 0;
    if (r < r_first) {
      for (int k = old_first; k < old_last; ++k) {
        const int old_index = cache.lattice_begin + k;
        change.to_new[static_cast<size_t>(old_index)] = add_point(cache.region.points[static_cast<size_t>(old_index)], -1, -1);
        next.column.push_back(cache.column[static_cast<size_t>(k)]);
        next.lifted.push_back(cache.lifted[static_cast<size_t>(k)]);
        next.lifted_final.push_back(cache.lifted_final[static_cast<size_t>(k)]);
      }
      next.row_start.push_back(static_cast<int>(next.column.size()));
      continue;
    }
    auto& crossings = row_crossings[static_cast<size_t>(r)];
    std::sort(crossings.begin(), crossings.end());
    int winding = 0;  // of the crossings right of the point
    for (const auto& crossing : crossings) winding += crossing.second;
    size_t passed = 0;
    int old_k = old_first;  // the last sample's points of this row, by column
    for (int c = 0; (c + 0.5 * (r % 2)) * w < extent.x(); ++c) {
      const Vec2 p((c + 0.5 * (r % 2)) * w, r * row);
      for (; passed < crossings.size() && crossings[passed].first <= p.x(); ++passed) winding -= crossings[passed].second;
      if (p.x() <= 0 || winding <= 0) continue;
      bool near = false;
      boundary_cells.visit_cells(frame.cell_of(Vec3(p.x(), p.y(), 0)), frame.cell_of(Vec3(p.x(), p.y(), 0)), [&](int e) {
        const auto& edge = region.boundary[static_cast<size_t>(e)];
        near = near || distance_to_segment(p, region.points[static_cast<size_t>(edge[0])], region.points[static_cast<size_t>(edge[1])]) < gap;
      });
      if (near) continue;
      // Moved off the lattice by a thousandth of w, the same way at every sample (a hash of
      // its row and column): six lattice neighbours lie on one circle around each point, and
      // every such empty-circle test would take the triangulation's exact (slow) path.
      const auto jitter = [&](std::uint64_t salt) {
        const std::uint64_t x = mix64((static_cast<std::uint64_t>(r) << 32) ^ static_cast<std::uint64_t>(c) ^ salt);
        return (static_cast<double>(x >> 11) / 9007199254740992.0 - 0.5) * 1e-3 * w;
      };
      const Vec2 jittered = p + Vec2(jitter(1), jitter(2));
      const int index = add_point(jittered, -1, -1);
      next.column.push_back(c);
      next.lifted.emplace_back(Vec3::Zero());
      next.lifted_final.push_back(0);
      if (!incremental) continue;
      // Against the last sample's row: the points it had at lower columns are gone, this one
      // (same row and column, same point) kept or added.
      for (; old_k < old_last && cache.column[static_cast<size_t>(old_k)] < c; ++old_k)
        change.t_change = std::min(change.t_change, cache.region.points[static_cast<size_t>(cache.lattice_begin + old_k)].y());
      if (old_k < old_last && cache.column[static_cast<size_t>(old_k)] == c) {
        change.to_new[static_cast<size_t>(cache.lattice_begin + old_k)] = index;
        next.lifted.back() = cache.lifted[static_cast<size_t>(old_k)];
        next.lifted_final.back() = cache.lifted_final[static_cast<size_t>(old_k)];
        ++old_k;
      } else {
        change.t_change = std::min(change.t_change, jittered.y());
      }
    }
    if (incremental)
      for (; old_k < old_last; ++old_k)
        change.t_change = std::min(change.t_change, cache.region.points[static_cast<size_t>(cache.lattice_begin + old_k)].y());
    next.row_start.push_back(static_cast<int>(next.column.size()));
  }
  // Rows the last sample had above this one's (none while the stroke goes forward): gone.
  if (const int new_rows = static_cast<int>(next.row_start.size()) - 1; incremental && new_rows < old_rows)
    for (int k = cache.row_start[static_cast<size_t>(new_rows)]; k < static_cast<int>(cache.column.size()); ++k)
      change.t_change = std::min(change.t_change, cache.region.points[static_cast<size_t>(cache.lattice_begin + k)].y());
}

}  // namespace incise::physics
