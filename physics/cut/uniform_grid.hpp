#pragma once
// The one uniform grid of the cutting code: items (points, boxes, triangles, edges) binned in
// the cells of a dense grid over a box, for the searches by position (nearest integration
// point, everything within a box, a segment's candidates, rings of cells around a point).
//
// Cells are compressed rows: per cell its items in increasing index order. Every visit goes
// through the cells in one fixed order (k, then j, then i, increasing; within a cell, items
// increasing), so what a visit sees first depends only on the items and the cells: clients
// whose results hang on the visit order (the front's edge crossings are numbered in it) get
// the same order for the same frame. Clients whose answer must not depend on the frame at
// all (nearest up to a tolerance, lowest index among ties) sort or min over what they saw.
//
// The frame (GridCells) is the client's choice: its origin, cell side, and cell range. The
// cell of x along an axis is floor((x - origin) / cell) - first, formed as a double and
// clamped to the grid, so far, infinite or NaN coordinates fall in a border cell and a
// query box always visits the cells it overlaps.

#include "physics/core/model.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <limits>
#include <vector>

namespace incise::physics {

using GridCell = std::array<long long, 3>;

// Cells of side `cell` on the lattice from `origin`: the grid holds lattice cells
// first .. first + count - 1 per axis.
struct GridCells {
  Vec3 origin = Vec3::Zero();
  double cell = 1;
  GridCell first{0, 0, 0}, count{0, 0, 0};

  // The lattice cell holding x along an axis (unbounded, but kept within +-2^52 so that it
  // converts exactly; NaN stays NaN).
  double lattice(int axis, double x) const {
    return std::clamp(std::floor((x - origin[axis]) / cell), -4503599627370496.0, 4503599627370496.0);
  }
  // The grid's cell holding x along an axis, clamped to the grid (NaN gives cell 0).
  long long cell_of(int axis, double x) const {
    const double c = lattice(axis, x) - static_cast<double>(first[axis]);
    return c >= 0 ? static_cast<long long>(std::min(c, static_cast<double>(count[axis] - 1))) : 0;
  }
  GridCell cell_of(const Vec3& p) const { return {cell_of(0, p[0]), cell_of(1, p[1]), cell_of(2, p[2])}; }
  // The grid's cell holding p, not clamped (it may lie outside the grid; p finite).
  GridCell unclamped_cell_of(const Vec3& p) const {
    GridCell c{};
    for (int axis = 0; axis < 3; ++axis) c[axis] = static_cast<long long>(lattice(axis, p[axis])) - first[axis];
    return c;
  }
  // The grid's cells overlapping [lo, hi], clamped; all of them along an axis where a bound is
  // NaN.
  void range(const Vec3& lo, const Vec3& hi, GridCell& from, GridCell& to) const {
    for (int axis = 0; axis < 3; ++axis) {
      if (std::isnan(lo[axis]) || std::isnan(hi[axis])) {
        from[axis] = 0, to[axis] = count[axis] - 1;
      } else {
        from[axis] = cell_of(axis, lo[axis]), to[axis] = cell_of(axis, hi[axis]);
      }
    }
  }
  long long total() const { return count[0] * count[1] * count[2]; }
  bool inside(long long i, long long j, long long k) const {
    return i >= 0 && j >= 0 && k >= 0 && i < count[0] && j < count[1] && k < count[2];
  }
  std::size_t index(long long i, long long j, long long k) const {
    return static_cast<std::size_t>(i + count[0] * (j + count[1] * k));
  }
  // The lattice cells from the one holding lo to the one holding hi (origin and cell as set).
  void cover(const Vec3& lo, const Vec3& hi) {
    for (int axis = 0; axis < 3; ++axis) {
      first[axis] = static_cast<long long>(lattice(axis, lo[axis]));
      count[axis] = static_cast<long long>(lattice(axis, hi[axis])) - first[axis] + 1;
    }
  }
  // The cells over [lo, hi] on the lattice from `origin`, of side `cell` times `growth` as
  // often as it takes to have at most `most` of them (coarser for spread-out items).
  static GridCells fit(const Vec3& origin, const Vec3& lo, const Vec3& hi, double cell, double most, double growth = 2) {
    GridCells grid;
    grid.origin = origin;
    grid.cell = cell;
    for (;;) {
      grid.cover(lo, hi);
      if (static_cast<double>(grid.count[0]) * static_cast<double>(grid.count[1]) * static_cast<double>(grid.count[2]) <= most)
        return grid;
      grid.cell *= growth;
    }
  }
};

class UniformGrid {
 public:
  GridCells cells;

  bool empty() const { return items_.empty() && large_.empty(); }
  std::size_t slots() const { return items_.size(); }  // items binned, once per cell they are in
  const std::vector<int>& apart() const { return large_; }
  void clear() {
    cells.count = {0, 0, 0};
    start_.clear(), items_.clear(), large_.clear(), stamp_.clear(), added_head_.clear(), added_.clear();
  }
  // Bins items 0 .. n - 1: cells_of(i, from, to) sets the grid cells of item i (within the
  // grid, as GridCells::range gives them) and says where it goes: 0 (or false) nowhere, 1 (or
  // true) in those cells, 2 kept apart (every query that visits each item once visits it).
  template <class CellsOf>
  void build(const GridCells& frame, int n, CellsOf&& cells_of) {
    cells = frame;
    start_.clear(), items_.clear(), large_.clear(), added_head_.clear(), added_.clear();
    if (cells.total() > 0) start_.assign(static_cast<std::size_t>(cells.total()) + 1, 0);
    stamp_.assign(static_cast<std::size_t>(std::max(n, 0)), 0u);
    query_ = 0;
    // Per item its cells (or none), found once: counted, then filled.
    std::vector<std::array<GridCell, 2>> ranges(static_cast<std::size_t>(std::max(n, 0)));
    std::vector<std::uint8_t> binned(ranges.size(), 0);
    for (int item = 0; item < n; ++item) {
      auto& [from, to] = ranges[static_cast<std::size_t>(item)];
      const int place = static_cast<int>(cells_of(item, from, to));
      if (place == 2) large_.push_back(item);
      if (place != 1 || start_.empty() || to[0] < from[0] || to[1] < from[1] || to[2] < from[2]) continue;
      binned[static_cast<std::size_t>(item)] = 1;
      for_cells(from, to, [&](std::size_t c) { ++start_[c + 1]; });
    }
    if (start_.empty()) return;
    for (std::size_t c = 1; c < start_.size(); ++c) start_[c] += start_[c - 1];
    items_.resize(static_cast<std::size_t>(start_.back()));
    std::vector<int> fill(start_.begin(), start_.end() - 1);
    for (int item = 0; item < n; ++item)
      if (binned[static_cast<std::size_t>(item)]) {
        const auto& [from, to] = ranges[static_cast<std::size_t>(item)];
        for_cells(from, to, [&](std::size_t c) { items_[static_cast<std::size_t>(fill[c]++)] = item; });
      }
  }
  // Adds item (above every item so far) after the build, without binning all again: in the
  // grid cells from .. to (within the grid), or kept apart (`apart`). Its cells list it after
  // their compressed rows (the latest added first). For a set that grows by a few items at a
  // time between many queries (the rest cut); build again when many were added.
  void add(int item, const GridCell& from, const GridCell& to, bool apart = false) {
    if (static_cast<std::size_t>(item) >= stamp_.size()) stamp_.resize(static_cast<std::size_t>(item) + 1, 0u);
    if (apart) {
      large_.push_back(item);
      return;
    }
    if (start_.empty()) return;
    if (added_head_.empty()) added_head_.assign(static_cast<std::size_t>(cells.total()), -1);
    for_cells(from, to, [&](std::size_t c) {
      added_.push_back({item, added_head_[c]});
      added_head_[c] = static_cast<int>(added_.size()) - 1;
    });
  }
  std::size_t added() const { return added_.size(); }  // slots added since the build

  // Points, each in the cell holding it.
  void build_points(const GridCells& frame, const std::vector<Vec3>& points) {
    build(frame, static_cast<int>(points.size()), [&](int i, GridCell& from, GridCell& to) {
      from = to = frame.cell_of(points[static_cast<std::size_t>(i)]);
      return true;
    });
  }
  // Boxes, each in the cells it overlaps.
  void build_boxes(const GridCells& frame, const std::vector<std::array<Vec3, 2>>& boxes) {
    build(frame, static_cast<int>(boxes.size()), [&](int i, GridCell& from, GridCell& to) {
      frame.range(boxes[static_cast<std::size_t>(i)][0], boxes[static_cast<std::size_t>(i)][1], from, to);
      return true;
    });
  }

  // Calls visit(item) for every item binned in the grid cells from .. to (inclusive, within
  // the grid), in the grid's order: an item over several of them is visited once per cell.
  // Items kept apart are not visited.
  template <class Visit>
  void visit_cells(const GridCell& from, const GridCell& to, Visit&& visit) const {
    if (start_.empty()) return;
    for (long long k = from[2]; k <= to[2]; ++k)
      for (long long j = from[1]; j <= to[1]; ++j)
        for (long long i = from[0]; i <= to[0]; ++i) {
          visit_cell(cells.index(i, j, k), visit);
        }
  }
  // The same over the cells overlapping [lo, hi] (clamped to the grid; see GridCells::range).
  template <class Visit>
  void visit_box(const Vec3& lo, const Vec3& hi, Visit&& visit) const {
    GridCell from{}, to{};
    cells.range(lo, hi, from, to);
    visit_cells(from, to, visit);
  }
  // Every item in the cells overlapping [lo, hi] and every item kept apart, each once: those
  // kept apart first, then the binned ones in the grid's order (an item at the first cell it
  // is met in). Not safe to call concurrently on one grid (the once is a stamp per item).
  template <class Visit>
  void visit_box_once(const Vec3& lo, const Vec3& hi, Visit&& visit) const {
    for (const int item : large_) visit(item);
    if (start_.empty()) return;
    if (++query_ == 0) {  // the stamps wrapped: forget them all
      std::fill(stamp_.begin(), stamp_.end(), 0u);
      query_ = 1;
    }
    visit_box(lo, hi, [&](int item) {
      unsigned& stamp = stamp_[static_cast<std::size_t>(item)];
      if (stamp == query_) return;
      stamp = query_;
      visit(item);
    });
  }
  // Calls visit(item) for the items in the cells of the shell at Chebyshev distance r from
  // the grid cell `centre` (which may lie outside the grid; cells outside it hold nothing),
  // in the grid's order: the shells r = 0, 1, ... visit every cell once, nearest shell first
  // (a nearest-point search by growing shells).
  template <class Visit>
  void visit_shell(const GridCell& centre, long long r, Visit&& visit) const {
    if (start_.empty()) return;
    for (long long dz = -r; dz <= r; ++dz)
      for (long long dy = -r; dy <= r; ++dy) {
        const bool on_shell = std::abs(dz) == r || std::abs(dy) == r;
        for (long long dx = -r; dx <= r; dx += on_shell ? 1 : std::max<long long>(2 * r, 1)) {
          const long long i = centre[0] + dx, j = centre[1] + dy, k = centre[2] + dz;
          if (cells.inside(i, j, k)) visit_cell(cells.index(i, j, k), visit);
        }
      }
  }

 private:
  template <class Visit>
  void visit_cell(std::size_t c, Visit& visit) const {
    for (int s = start_[c]; s < start_[c + 1]; ++s) visit(items_[static_cast<std::size_t>(s)]);
    if (!added_head_.empty())
      for (int s = added_head_[c]; s >= 0; s = added_[static_cast<std::size_t>(s)][1]) visit(added_[static_cast<std::size_t>(s)][0]);
  }
  template <class Cell>
  void for_cells(const GridCell& from, const GridCell& to, Cell&& cell) const {
    for (long long k = from[2]; k <= to[2]; ++k)
      for (long long j = from[1]; j <= to[1]; ++j)
        for (long long i = from[0]; i <= to[0]; ++i) cell(cells.index(i, j, k));
  }

  std::vector<int> start_;   // per cell, its first slot in items_ (one past the last: the end)
  std::vector<int> items_;   // per slot, its item
  std::vector<int> large_;   // items kept apart, increasing
  std::vector<int> added_head_;  // per cell, its latest slot in added_ (-1: none); empty: none added
  std::vector<std::array<int, 2>> added_;  // per slot added since the build: its item, the cell's next slot
  mutable std::vector<unsigned> stamp_;  // per item: the visit_box_once query that last met it
  mutable unsigned query_ = 0;
};

// Points binned about one per cell: cells of side `spacing` over their box, coarser (doubled)
// while there would be more than 8 cells per point (and 64). False, and the grid empty, when
// there is no point or one is not finite.
inline bool bin_points(UniformGrid& grid, const std::vector<Vec3>& points, double spacing) {
  grid.clear();
  if (points.empty()) return false;
  Vec3 lo = points[0], hi = points[0];
  for (const Vec3& p : points) {
    if (!p.allFinite()) return false;
    lo = lo.cwiseMin(p), hi = hi.cwiseMax(p);
  }
  grid.build_points(GridCells::fit(lo, lo, hi, spacing, 8.0 * static_cast<double>(points.size()) + 64), points);
  return true;
}

}  // namespace incise::physics
