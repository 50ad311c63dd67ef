#include "physics/fem/surface_snap.hpp"

#include <Eigen/Geometry>

#include <cmath>

namespace incise::physics {

namespace {

double signed_volume(const Vector& x, const std::array<int, 4>& t) {
  Vec3 a = x.segment<3>(3 * t[0]);
  Vec3 b = x.segment<3>(3 * t[1]);
  Vec3 c = x.segment<3>(3 * t[2]);
  Vec3 d = x.segment<3>(3 * t[3]);
  return (b - a).dot((c - a).cross(d - a)) / 6.0;
}

// Parameter s in [lo, hi] where inside(p + s n) changes, given it differs at the two ends.
double bisect(const std::function<bool(const Vec3&)>& inside, const Vec3& p, const Vec3& n, double lo,
              double hi, bool inside_at_lo, int bisections) {
  for (int k = 0; k < bisections; ++k) {
    double mid = 0.5 * (lo + hi);
    if (inside(p + mid * n) == inside_at_lo)
      lo = mid;
    else
      hi = mid;
  }
  return 0.5 * (lo + hi);
}

}  // namespace

SnapReport snap_boundary_to_surface(TetMesh& mesh, const std::function<bool(const Vec3&)>& inside,
                                    double reach, double min_volume_ratio, int bisections) {
  SnapReport report;
  const int n = static_cast<int>(mesh.rest.size() / 3);
  const auto boundary = boundary_triangles(mesh.tets);
  std::vector<Vec3> normal(n, Vec3::Zero());
  std::vector<uint8_t> on_boundary(n, 0);
  for (const auto& f : boundary) {
    Vec3 a = mesh.rest.segment<3>(3 * f[0]);
    Vec3 area = (mesh.rest.segment<3>(3 * f[1]) - a).cross(mesh.rest.segment<3>(3 * f[2]) - a);
    for (int v : f) {
      normal[v] += area;
      on_boundary[v] = 1;
    }
  }
  std::vector<std::vector<int>> tets_of(n);
  for (std::size_t t = 0; t < mesh.tets.size(); ++t)
    for (int v : mesh.tets[t]) tets_of[v].push_back(static_cast<int>(t));

  // Quality is judged against the voxel elements, so that successive moves of the corners of
  // one element cannot flatten it step by step.
  std::vector<double> original_volume(mesh.tets.size());
  for (std::size_t t = 0; t < mesh.tets.size(); ++t) original_volume[t] = signed_volume(mesh.rest, mesh.tets[t]);

  // Two passes: a node held back because a neighbour had not moved yet gets a second try
  // once its neighbours sit on the surface.
  enum Status : uint8_t { interior, left, partly, moved };
  std::vector<uint8_t> status(n, interior);
  for (int v = 0; v < n; ++v)
    if (on_boundary[v]) status[v] = left;
  const int steps = 12;  // coarse march before bisection, so a thin feature is not jumped over
  for (int pass = 0; pass < 2; ++pass) {
    for (int v = 0; v < n; ++v) {
      if (status[v] == interior || status[v] == moved) continue;
      double length = normal[v].norm();
      if (!(length > 0)) continue;
      Vec3 direction = normal[v] / length;
      Vec3 p = mesh.rest.segment<3>(3 * v);
      bool p_inside = inside(p);
      // Inside: the surface is further out; outside: it is back in along -normal.
      double sign = p_inside ? 1.0 : -1.0;
      double found = std::nan("");
      double previous = 0;
      for (int k = 1; k <= steps; ++k) {
        double s = sign * reach * k / steps;
        if (inside(p + s * direction) != p_inside) {
          found = bisect(inside, p, direction, previous, s, p_inside, bisections);
          break;
        }
        previous = s;
      }
      if (std::isnan(found)) continue;
      for (double fraction : {1.0, 0.5, 0.25}) {
        mesh.rest.segment<3>(3 * v) = p + fraction * found * direction;
        double worst = 1;
        for (int t : tets_of[v])
          worst = std::min(worst, signed_volume(mesh.rest, mesh.tets[t]) / original_volume[t]);
        if (worst >= min_volume_ratio) {
          status[v] = fraction == 1.0 ? moved : partly;
          break;
        }
        mesh.rest.segment<3>(3 * v) = p;
      }
    }
  }
  for (int v = 0; v < n; ++v) {
    report.moved += status[v] == moved;
    report.moved_partly += status[v] == partly;
    report.left += status[v] == left;
    report.boundary_nodes += status[v] != interior;
  }
  for (std::size_t t = 0; t < mesh.tets.size(); ++t)
    report.min_volume_ratio =
        std::min(report.min_volume_ratio, signed_volume(mesh.rest, mesh.tets[t]) / original_volume[t]);
  return report;
}

}  // namespace incise::physics
