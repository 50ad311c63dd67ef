#include "physics/core/nearest_triangles.hpp"

#include "physics/core/contact.hpp"
#include "physics/core/triangle_grid.hpp"

#include <algorithm>
#include <cmath>

namespace incise::physics {

Vec3 face_normal(const Vector& x, const std::array<int, 3>& triangle) {
  const Vec3 a = x.segment<3>(3 * triangle[0]), b = x.segment<3>(3 * triangle[1]), c = x.segment<3>(3 * triangle[2]);
  return (b - a).cross(c - a);
}

namespace {

bool skipped(const std::vector<std::uint8_t>& skip, std::size_t t) { return t < skip.size() && skip[t]; }

double distance_to(const Vector& x, const std::array<int, 3>& tri, const Vec3& p) {
  return (p - closest_point_on_triangle(p, x.segment<3>(3 * tri[0]), x.segment<3>(3 * tri[1]), x.segment<3>(3 * tri[2])))
      .norm();
}

// The box every triangle that can matter to some point meets: per point, the cube of the
// hint's bound on its nearest distance, widened by a relative and an absolute margin far
// above the rounding of the distances (the grid's own margins are 1e-6 and 1e-9 of its
// extent). False where there is no bound (no usable hint triangle, a point or a distance
// that is not finite): every usable triangle is taken then.
bool region(const Vector& x, const std::vector<std::array<int, 3>>& surface, const std::vector<std::uint8_t>& skip,
            const std::vector<Vec3>& points, const std::vector<int>& hint, Vec3& low, Vec3& high) {
  std::vector<int> usable;
  for (int t : hint) {
    const auto s = static_cast<std::size_t>(t);
    if (t >= 0 && s < surface.size() && !skipped(skip, s) && face_normal(x, surface[s]).squaredNorm() > 0)
      usable.push_back(t);
  }
  if (usable.empty()) return false;
  low = Vec3::Constant(std::numeric_limits<double>::infinity());
  high = -low;
  for (const Vec3& p : points) {
    double bound = std::numeric_limits<double>::infinity();
    for (int t : usable) bound = std::min(bound, distance_to(x, surface[static_cast<std::size_t>(t)], p));
    if (!std::isfinite(bound) || !p.allFinite()) return false;
    const double margin = bound * 1e-5 + 1e-8 * (p.cwiseAbs().maxCoeff() + bound) + std::numeric_limits<double>::min();
    low = low.cwiseMin(p - Vec3::Constant(bound + margin));
    high = high.cwiseMax(p + Vec3::Constant(bound + margin));
  }
  return true;
}

}  // namespace

std::vector<NearestTriangle> nearest_triangles(const Vector& x, const std::vector<std::array<int, 3>>& surface,
                                               const std::vector<std::uint8_t>& skip, const std::vector<Vec3>& points,
                                               std::vector<int>* hint, Executor& executor) {
  std::vector<NearestTriangle> out(points.size());
  if (points.empty()) return out;
  Vec3 low, high;
  const bool bounded = hint && region(x, surface, skip, points, *hint, low, high);
  // The usable triangles whose box meets the region, chunk by chunk (each chunk's in order).
  constexpr int chunk = 8192;
  const int chunks = static_cast<int>((surface.size() + chunk - 1) / chunk);
  std::vector<std::vector<int>> kept(static_cast<std::size_t>(chunks));
  executor.parallel_for(chunks, [&](int begin, int end) {
    for (int k = begin; k < end; ++k) {
      std::vector<int>& list = kept[static_cast<std::size_t>(k)];
      const std::size_t last = std::min(surface.size(), static_cast<std::size_t>(k + 1) * chunk);
      for (std::size_t t = static_cast<std::size_t>(k) * chunk; t < last; ++t) {
        if (skipped(skip, t)) continue;
        const auto& tri = surface[t];
        if (bounded) {
          // A box apart from the region's is farther than every point's nearest (not finite: kept).
          const Vec3 a = x.segment<3>(3 * tri[0]), b = x.segment<3>(3 * tri[1]), c = x.segment<3>(3 * tri[2]);
          if ((a.cwiseMax(b).cwiseMax(c).array() < low.array()).any() ||
              (a.cwiseMin(b).cwiseMin(c).array() > high.array()).any())
            continue;
        }
        if (face_normal(x, tri).squaredNorm() > 0) list.push_back(static_cast<int>(t));
      }
    }
  });
  std::vector<int> triangles;
  for (const std::vector<int>& list : kept) triangles.insert(triangles.end(), list.begin(), list.end());
  const TriangleGrid grid(x, surface, std::move(triangles));
  // Each point's scan is its own: the points on the threads, each range with its scratch.
  constexpr int points_per_thread = 8;
  executor.parallel_for(static_cast<int>(points.size()), [&](int begin, int end) {
    TriangleGrid::Scratch scratch;
    std::vector<int> candidates;
    for (auto i = static_cast<std::size_t>(begin); i < static_cast<std::size_t>(end); ++i) {
      const Vec3& p = points[i];
      NearestTriangle& nearest = out[i];
      grid.candidates(p, candidates, scratch);
      for (int slot : candidates) {
        // The box's distance bounds the triangle's from below: most triangles are skipped here.
        if ((grid.lo(slot) - p).cwiseMax(p - grid.hi(slot)).cwiseMax(Vec3::Zero()).norm() >= nearest.distance) continue;
        const int t = grid.triangle(slot);
        const auto& tri = surface[static_cast<std::size_t>(t)];
        const Vec3 q = closest_point_on_triangle(p, x.segment<3>(3 * tri[0]), x.segment<3>(3 * tri[1]), x.segment<3>(3 * tri[2]));
        const double d = (p - q).norm();
        if (d < nearest.distance) nearest = {t, d, q};
      }
    }
  }, points_per_thread);
  if (hint) {
    hint->clear();
    for (const NearestTriangle& nearest : out)
      if (nearest.triangle >= 0 && std::find(hint->begin(), hint->end(), nearest.triangle) == hint->end())
        hint->push_back(nearest.triangle);
  }
  return out;
}

}  // namespace incise::physics
