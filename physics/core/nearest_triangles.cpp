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
                                               std::vector<int>* hint) {
  std::vector<NearestTriangle> out(points.size());
  if (points.empty()) return out;
  Vec3 low, high;
  const bool bounded = hint && region(x, surface, skip, points, *hint, low, high);
  std::vector<int> triangles;
  for (std::size_t t = 0; t < surface.size(); ++t) {
    if (skipped(skip, t)) continue;
    const auto& tri = surface[t];
    if (bounded) {
      // A box apart from the region's is farther than every point's nearest (not finite: kept).
      const Vec3 a = x.segment<3>(3 * tri[0]), b = x.segment<3>(3 * tri[1]), c = x.segment<3>(3 * tri[2]);
      if ((a.cwiseMax(b).cwiseMax(c).array() < low.array()).any() ||
          (a.cwiseMin(b).cwiseMin(c).array() > high.array()).any())
        continue;
    }
    if (face_normal(x, tri).squaredNorm() > 0) triangles.push_back(static_cast<int>(t));
  }
  TriangleGrid grid(x, surface, std::move(triangles));
  std::vector<int> candidates;
  for (std::size_t i = 0; i < points.size(); ++i) {
    const Vec3& p = points[i];
    NearestTriangle& nearest = out[i];
    grid.candidates(p, candidates);
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
  if (hint) {
    hint->clear();
    for (const NearestTriangle& nearest : out)
      if (nearest.triangle >= 0 && std::find(hint->begin(), hint->end(), nearest.triangle) == hint->end())
        hint->push_back(nearest.triangle);
  }
  return out;
}

}  // namespace incise::physics
