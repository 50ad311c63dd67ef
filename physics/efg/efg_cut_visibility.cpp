// Whether a build-time cut hides one point from another: CutRectangle::blocks, and the build's
// test over EfgSettings::cuts with front_hidden_beyond.
#include "physics/efg/efg_build.hpp"

#include <cmath>
#include <limits>

namespace incise::physics {

namespace efg_build {

// (s, r, signed distance) of a point in a cut's frame: corner + s edge_u + r edge_v + d n.
Vec3 cut_frame(const CutRectangle& cut, const Vec3& point) {
  const Vec3 normal = cut.edge_u.cross(cut.edge_v).normalized();
  const Vec3 relative = point - cut.corner;
  const double u_squared = cut.edge_u.squaredNorm(), v_squared = cut.edge_v.squaredNorm();
  const double edges_dot = cut.edge_u.dot(cut.edge_v);
  const double along_u = relative.dot(cut.edge_u), along_v = relative.dot(cut.edge_v);
  const double determinant = u_squared * v_squared - edges_dot * edges_dot;
  return Vec3((along_u * v_squared - along_v * edges_dot) / determinant,
              (along_v * u_squared - along_u * edges_dot) / determinant, normal.dot(relative));
}

// Whether the settings' build-time cuts hide `to` from `from` (EfgSettings::cuts,
// front_hidden_beyond).
bool is_blocked(const EfgSettings& s, const Vec3& from, const Vec3& to) {
  for (const CutRectangle& cut : s.cuts) {
    if (cut.blocks(from, to)) return true;
    if (!(s.front_hidden_beyond < std::numeric_limits<double>::infinity())) continue;
    // A particle on the crack front (the rim edge r = 0), seen from a point on the cut's
    // negative side and beside the cut (r > 0).
    const Vec3 particle = cut_frame(cut, to), point = cut_frame(cut, from);
    const double scale = std::sqrt(cut.edge_v.squaredNorm());
    if (std::abs(particle.z()) < 1e-9 * scale && std::abs(particle.y()) < 1e-9 &&
        particle.x() > 0 && particle.x() < 1 && point.z() < 0 &&
        point.y() * scale > s.front_hidden_beyond) {
      return true;
    }
  }
  return false;
}

}  // namespace efg_build

bool CutRectangle::blocks(const Vec3& from, const Vec3& to) const {
  const Vec3 normal = edge_u.cross(edge_v);
  if (!(normal.squaredNorm() > 0)) return false;
  const double distance_from = normal.dot(from - corner);
  const double distance_to = normal.dot(to - corner);
  if ((distance_from >= 0) == (distance_to >= 0)) return false;
  const double t = distance_from / (distance_from - distance_to);
  const Vec3 relative = from + t * (to - from) - corner;
  // Coordinates (s, r) of the crossing point in the parallelogram's own frame.
  const double u_squared = edge_u.squaredNorm(), v_squared = edge_v.squaredNorm();
  const double edges_dot = edge_u.dot(edge_v);
  const double along_u = relative.dot(edge_u), along_v = relative.dot(edge_v);
  const double determinant = u_squared * v_squared - edges_dot * edges_dot;
  const double s = (along_u * v_squared - along_v * edges_dot) / determinant;
  const double r = (along_v * u_squared - along_u * edges_dot) / determinant;
  // Open parallelogram: a link through the rim is not cut, so particles on the crack front
  // stay shared by both sides, like the nodes of a conforming FEM cut.
  constexpr double tolerance = 1e-12;
  return s > tolerance && s < 1 - tolerance && r > tolerance && r < 1 - tolerance;
}

}  // namespace incise::physics
