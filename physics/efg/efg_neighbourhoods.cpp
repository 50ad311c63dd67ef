// The build's neighbourhoods (seed-004 §1.3): each element's particle-cell corners, nearest
// first, the corners a build-time cut hides replaced by visible particles on the element's side.
#include "physics/efg/efg_build.hpp"
#include "physics/efg/efg_detail.hpp"
#include "physics/efg/mls.hpp"

#include <algorithm>
#include <limits>
#include <string>
#include <utility>

namespace incise::physics {

namespace {

using efg_detail::fail;
using efg_detail::format_point;
using efg_detail::longest_row;

}  // namespace

namespace efg_build {

// With 4, the nearest corner and its three edge neighbours in the cell: the 4 nearest
// corners when the point is inside the cell, and never coplanar when it is outside.
void nearest_corners(const ParticleGrid& grid, const Vec3& centre, std::array<int, 3> cell, int count,
                     std::vector<int>& row) {
  std::array<std::pair<double, int>, 8> corners;
  for (int c = 0; c < 8; ++c) {
    const int index = grid.index(cell[0] + (c & 1), cell[1] + ((c >> 1) & 1),
                                    cell[2] + ((c >> 2) & 1));
    corners[c] = {(grid.position(index) - centre).squaredNorm(), c};
  }
  const auto corner_index = [&](int c) {
    return grid.index(cell[0] + (c & 1), cell[1] + ((c >> 1) & 1), cell[2] + ((c >> 2) & 1));
  };
  const auto by_distance = [&](const std::pair<double, int>& left,
                               const std::pair<double, int>& right) {
    return left.first != right.first ? left.first < right.first
                                     : corner_index(left.second) < corner_index(right.second);
  };
  std::sort(corners.begin(), corners.end(), by_distance);
  row.clear();
  if (count == 8) {
    for (const auto& corner : corners) row.push_back(corner_index(corner.second));
    return;
  }
  const int nearest = corners[0].second;
  std::array<std::pair<double, int>, 4> tetrahedron{corners[0]};
  for (int bit = 0; bit < 3; ++bit) {
    const int c = nearest ^ (1 << bit);
    tetrahedron[bit + 1] = {(grid.position(corner_index(c)) - centre).squaredNorm(), c};
  }
  std::sort(tetrahedron.begin(), tetrahedron.end(), by_distance);
  for (const auto& corner : tetrahedron) row.push_back(corner_index(corner.second));
}

}  // namespace efg_build

using efg_build::ParticleGrid;
using efg_build::is_blocked;
using efg_build::nearest_corners;

std::vector<std::vector<int>> CorotationalEfg::select_neighbourhoods(const ParticleGrid& grid) const {
  // Neighbourhoods in grid-particle indices: the corners of the element's particle cell,
  // nearest first (ties to the lower index), 8 or the 4 nearest (seed-004 §1.3).
  const EfgSettings& s = building_->settings;
  const int elements = element_count();
  std::vector<std::vector<int>> rows(elements);
  for (int e = 0; e < elements; ++e) {
    const std::array<int, 3>& cube = building_->element_cubes[e];
    const std::array<int, 3> cell{cube[0] / 2, cube[1] / 2, cube[2] / 2};
    nearest_corners(grid, building_->centres[e], cell, s.neighbours, rows[e]);
    if (s.cuts.empty()) continue;
    const auto visible = [&](int index) {
      return !is_blocked(s, building_->centres[e], grid.position(index));
    };
    if (std::all_of(rows[e].begin(), rows[e].end(), visible)) continue;
    rows[e] = visible_neighbourhood(grid, e, cell, rows[e]);
  }
  return rows;
}

// A cut hides some of element e's cell corners `corners` (EfgSettings::cuts).
std::vector<int> CorotationalEfg::visible_neighbourhood(const ParticleGrid& grid, int e, const std::array<int, 3>& cell,
                                                        const std::vector<int>& corners) const {
  const EfgSettings& s = building_->settings;
  const auto visible = [&](int index) { return !is_blocked(s, building_->centres[e], grid.position(index)); };
  std::vector<Vec3> positions;

  // A cut hides some corners. The visible ones stay (they carry the coupling across the
  // uncut part, e.g. below a crack front), and each hidden corner is replaced by the particle
  // one step beyond its neighbour in the cell along an axis (the nearest such one that is
  // visible and new). An element whose cell the cut cuts off entirely thus gets the
  // neighbouring cell on its own side, keeping a cell-shaped, well-conditioned neighbourhood.
  std::vector<int> kept;
  std::vector<int> hidden;
  for (int index : corners) (visible(index) ? kept : hidden).push_back(index);
  for (int index : hidden) {
    const std::array<int, 3> corner = grid.coordinates(index);
    // The axis nearest the normal of the cut that hides the corner: stepping along it moves
    // away from the cut on the element's side, rather than around the crack front.
    int normal_axis = -1;
    if (s.replace_along_cut_normal) {
      for (const CutRectangle& cut : s.cuts) {
        if (!cut.blocks(building_->centres[e], grid.position(index))) continue;
        const Vec3 normal = cut.edge_u.cross(cut.edge_v).cwiseAbs();
        normal.maxCoeff(&normal_axis);
        break;
      }
    }
    double best_distance = std::numeric_limits<double>::infinity();
    int best = -1;
    for (int pass = 0; pass < 2 && best < 0; ++pass) for (int axis = 0; axis < 3; ++axis) {
      if (pass == 0 && normal_axis >= 0 && axis != normal_axis) continue;
      // The in-cell neighbour is one step towards the cell's other face on this axis.
      const int step = corner[axis] == cell[axis] ? 1 : -1;
      std::array<int, 3> beyond = corner;
      beyond[axis] += 2 * step;
      if (beyond[axis] < 0 || beyond[axis] >= grid.counts[axis]) continue;
      const int candidate = grid.index(beyond[0], beyond[1], beyond[2]);
      if (std::find(kept.begin(), kept.end(), candidate) != kept.end() || !visible(candidate)) {
        continue;
      }
      const double distance = (grid.position(candidate) - building_->centres[e]).squaredNorm();
      if (distance < best_distance || (distance == best_distance && candidate < best)) {
        best_distance = distance;
        best = candidate;
      }
    }
    if (best >= 0) kept.push_back(best);
  }
  // Still too few, or coplanar: add the nearest visible particles (ties to the lower index)
  // until there are enough spanning 3 dimensions.
  std::vector<std::pair<double, int>> candidates;
  for (int k = std::max(0, cell[2] - 2); k <= std::min(grid.counts[2] - 1, cell[2] + 3); ++k) {
    for (int j = std::max(0, cell[1] - 2); j <= std::min(grid.counts[1] - 1, cell[1] + 3); ++j) {
      for (int i = std::max(0, cell[0] - 2); i <= std::min(grid.counts[0] - 1, cell[0] + 3); ++i) {
        const int index = grid.index(i, j, k);
        if (std::find(kept.begin(), kept.end(), index) != kept.end() || !visible(index)) continue;
        candidates.push_back({(grid.position(index) - building_->centres[e]).squaredNorm(), index});
      }
    }
  }
  std::sort(candidates.begin(), candidates.end());
  const auto spans = [&](const std::vector<int>& row) {
    positions.clear();
    for (int index : row) positions.push_back(grid.position(index));
    return spans_three_dimensions(positions);
  };
  size_t next = 0;
  while (static_cast<int>(kept.size()) < longest_row &&
         (static_cast<int>(kept.size()) < s.neighbours || !spans(kept)) &&
         next < candidates.size()) {
    kept.push_back(candidates[next++].second);
  }
  if (!spans(kept)) {
    fail("element " + std::to_string(e) + " at " + format_point(building_->centres[e]) +
         " is cut off: no neighbourhood of visible particles spans 3 dimensions");
  }
  return kept;
}

}  // namespace incise::physics
