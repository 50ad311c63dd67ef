#include "physics/core/triangle_grid.hpp"

#include "physics/core/contact.hpp"

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <limits>
#include <utility>

namespace incise::physics {

namespace {

// About this many cells per used triangle at most: the grid's memory stays linear in the surface.
constexpr double kCellsPerTriangle = 4.0;

}  // namespace

TriangleGrid::TriangleGrid(const Vector& x, const std::vector<std::array<int, 3>>& surface,
                           const std::vector<std::uint8_t>& use)
    : x_(x), surface_(surface) {
  for (std::size_t t = 0; t < surface.size(); ++t)
    if (t >= use.size() || use[t]) used_.push_back(static_cast<int>(t));
  build();
}

TriangleGrid::TriangleGrid(const Vector& x, const std::vector<std::array<int, 3>>& surface, std::vector<int> triangles)
    : x_(x), surface_(surface), used_(std::move(triangles)) {
  build();
}

void TriangleGrid::build() {
  const std::size_t count = used_.size();
  lo_.resize(count);
  hi_.resize(count);
  Vec3 low = Vec3::Constant(std::numeric_limits<double>::infinity()), high = -low;
  double extent_sum = 0;
  for (std::size_t s = 0; s < count; ++s) {
    const auto& tri = surface_[static_cast<std::size_t>(used_[s])];
    const Vec3 a = x_.segment<3>(3 * tri[0]), b = x_.segment<3>(3 * tri[1]), c = x_.segment<3>(3 * tri[2]);
    lo_[s] = a.cwiseMin(b).cwiseMin(c);
    hi_[s] = a.cwiseMax(b).cwiseMax(c);
    if (!lo_[s].allFinite() || !hi_[s].allFinite()) finite_ = false;
    low = low.cwiseMin(lo_[s]);
    high = high.cwiseMax(hi_[s]);
    extent_sum += (hi_[s] - lo_[s]).maxCoeff();
  }
  if (used_.empty() || !finite_) return;
  const Vec3 size = high - low;
  slack_ = 1e-9 * size.norm() + std::numeric_limits<double>::min();
  // Cells about twice a triangle's box, coarser where that would make too many of them.
  cell_ = std::max(2.0 * extent_sum / static_cast<double>(count), 1e-6 * size.maxCoeff());
  if (!(cell_ > 0)) cell_ = 1.0;
  const double budget = kCellsPerTriangle * static_cast<double>(count) + 1;
  while (((size / cell_).array().floor() + 1).prod() > budget) cell_ *= 1.25;
  origin_ = low;
  for (int k = 0; k < 3; ++k) dims_[k] = static_cast<int>(std::floor(size[k] / cell_)) + 1;
  const auto range = [&](const Vec3& v, int k) {
    return std::clamp(static_cast<int>(std::floor((v[k] - origin_[k]) / cell_)), 0, dims_[k] - 1);
  };
  const auto index = [&](int i, int j, int l) { return (static_cast<std::size_t>(l) * dims_[1] + j) * dims_[0] + i; };
  start_.assign(static_cast<std::size_t>(dims_[0]) * dims_[1] * dims_[2] + 1, 0);
  // Two passes (count, then fill in slot order): each cell's list comes out sorted.
  for (int pass = 0; pass < 2; ++pass) {
    if (pass == 1) {
      for (std::size_t c = 1; c < start_.size(); ++c) start_[c] += start_[c - 1];
      items_.resize(static_cast<std::size_t>(start_.back()));
    }
    std::vector<int> fill = pass == 1 ? std::vector<int>(start_.begin(), start_.end() - 1) : std::vector<int>{};
    for (std::size_t s = 0; s < count; ++s) {
      for (int l = range(lo_[s], 2); l <= range(hi_[s], 2); ++l)
        for (int j = range(lo_[s], 1); j <= range(hi_[s], 1); ++j)
          for (int i = range(lo_[s], 0); i <= range(hi_[s], 0); ++i) {
            if (pass == 0) ++start_[index(i, j, l) + 1];
            else items_[static_cast<std::size_t>(fill[index(i, j, l)]++)] = static_cast<int>(s);
          }
    }
  }
}

double TriangleGrid::distance(const Vec3& p, int slot) const {
  const auto& tri = surface_[static_cast<std::size_t>(used_[static_cast<std::size_t>(slot)])];
  const Vec3 a = x_.segment<3>(3 * tri[0]), b = x_.segment<3>(3 * tri[1]), c = x_.segment<3>(3 * tri[2]);
  return (p - closest_point_on_triangle(p, a, b, c)).norm();
}

void TriangleGrid::all(std::vector<int>& out) const {
  out.resize(used_.size());
  for (std::size_t s = 0; s < out.size(); ++s) out[s] = static_cast<int>(s);
}

void TriangleGrid::candidates(const Vec3& p, std::vector<int>& out, Scratch& scratch) const {
  out.clear();
  if (used_.empty()) return;
  if (!finite_ || !p.allFinite()) return all(out);
  if (scratch.stamp.size() != used_.size()) {
    scratch.stamp.assign(used_.size(), 0);
    scratch.seen.assign(used_.size(), -1);
    scratch.query = 0;
  }
  std::vector<int>& stamp = scratch.stamp;
  std::vector<double>& seen = scratch.seen;
  const int query = ++scratch.query;
  std::array<int, 3> centre{};
  int rings = 0;  // past this ring every cell has been seen
  for (int k = 0; k < 3; ++k) {
    const double at = std::floor((p[k] - origin_[k]) / cell_);
    centre[k] = static_cast<int>(std::clamp(at, 0.0, static_cast<double>(dims_[k] - 1)));
    rings = std::max({rings, centre[k], dims_[k] - 1 - centre[k]});
  }
  double best = std::numeric_limits<double>::infinity();
  const auto reach = [&] { return best * (1 + 1e-6) + slack_; };
  const auto visit = [&](int i, int j, int l) {
    // A cell farther than the nearest so far (with the margins) holds no triangle that matters.
    const Vec3 cell_lo = origin_ + cell_ * Vec3(i, j, l), cell_hi = cell_lo + Vec3::Constant(cell_);
    if ((cell_lo - p).cwiseMax(p - cell_hi).cwiseMax(Vec3::Zero()).norm() > reach()) return;
    const std::size_t c = (static_cast<std::size_t>(l) * dims_[1] + j) * dims_[0] + i;
    for (int n = start_[c]; n < start_[c + 1]; ++n) {
      const int slot = items_[static_cast<std::size_t>(n)];
      const std::size_t s = static_cast<std::size_t>(slot);
      if (stamp[s] == query) continue;
      stamp[s] = query;
      out.push_back(slot);
      seen[s] = -1;  // its distance not computed: its box was no nearer than the nearest then
      if ((lo_[s] - p).cwiseMax(p - hi_[s]).cwiseMax(Vec3::Zero()).norm() < best) {
        seen[s] = distance(p, slot);
        best = std::min(best, seen[s]);
      }
    }
  };
  for (int ring = 0; ring <= rings; ++ring) {
    // The cells at Chebyshev distance `ring` from the centre's cell.
    for (int l = std::max(0, centre[2] - ring); l <= std::min(dims_[2] - 1, centre[2] + ring); ++l)
      for (int j = std::max(0, centre[1] - ring); j <= std::min(dims_[1] - 1, centre[1] + ring); ++j) {
        const bool shell = std::abs(l - centre[2]) == ring || std::abs(j - centre[1]) == ring;
        for (int i = std::max(0, centre[0] - ring); i <= std::min(dims_[0] - 1, centre[0] + ring); ++i)
          if (shell || std::abs(i - centre[0]) == ring) visit(i, j, l);
          else i = std::max(i, centre[0] + ring - 1);  // jump over the inside, seen already
      }
    // Every cell not yet seen is at least ring cells away: its triangles' boxes are farther
    // than the nearest by the margins (when one is found), so none of them can matter.
    if (static_cast<double>(ring) * cell_ > reach()) break;
  }
  // Of those seen, the ones within the nearest's distance (with the margins): their box, and
  // their own distance where it was computed. The others, farther by more than rounding, can
  // neither be the nearest nor make the scan skip it.
  const double within = reach();
  std::erase_if(out, [&](int slot) {
    const std::size_t s = static_cast<std::size_t>(slot);
    return seen[s] > within || (lo_[s] - p).cwiseMax(p - hi_[s]).cwiseMax(Vec3::Zero()).norm() > within;
  });
  std::sort(out.begin(), out.end());
}

}  // namespace incise::physics
