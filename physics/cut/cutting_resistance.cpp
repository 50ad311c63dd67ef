#include "physics/cut/cutting_resistance.hpp"

#include "physics/core/contact.hpp"
#include "physics/core/triangle_grid.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

namespace incise::physics {

std::vector<EdgePiece> edge_pieces(const std::vector<Vec3>& start, const std::vector<Vec3>& end, double spacing) {
  std::vector<EdgePiece> pieces;
  if (end.size() < 2 || start.size() != end.size() || !(spacing > 0)) return pieces;
  for (std::size_t i = 0; i + 1 < end.size(); ++i) {
    const Vec3 along = end[i + 1] - end[i];
    const double length = along.norm();
    if (!(length > 0)) continue;
    const int count = std::max(1, static_cast<int>(std::ceil(length / spacing)));
    for (int k = 0; k < count; ++k) {
      const double s = (k + 0.5) / count;
      EdgePiece piece;
      piece.point = end[i] + s * along;
      piece.tangent = along / length;
      piece.length = length / count;
      piece.motion = piece.point - (start[i] + s * (start[i + 1] - start[i]));
      pieces.push_back(piece);
    }
  }
  return pieces;
}

void mark_engaged(const Vector& x, const std::vector<std::array<int, 3>>& surface,
                  const std::vector<std::uint8_t>& cut_face, double reach, std::vector<EdgePiece>& pieces) {
  if (pieces.empty()) return;
  // The faces the scan looks at (not a cut face, not degenerate), in a grid: each piece scans
  // only the triangles near it (physics/core/triangle_grid.hpp), in the same order.
  std::vector<std::uint8_t> use(surface.size(), 0);
  std::vector<Vec3> faces(surface.size(), Vec3::Zero());
  for (std::size_t t = 0; t < surface.size(); ++t) {
    if (t < cut_face.size() && cut_face[t]) continue;
    const auto& tri = surface[t];
    const Vec3 a = x.segment<3>(3 * tri[0]), b = x.segment<3>(3 * tri[1]), c = x.segment<3>(3 * tri[2]);
    faces[t] = (b - a).cross(c - a);
    use[t] = faces[t].squaredNorm() > 0;
  }
  TriangleGrid grid(x, surface, use);
  std::vector<int> candidates;
  for (EdgePiece& piece : pieces) {
    const Vec3& p = piece.point;
    double nearest = std::numeric_limits<double>::infinity(), side = 1.0;
    grid.candidates(p, candidates);
    for (int t : candidates) {
      // The box's distance bounds the triangle's from below: most triangles are skipped here.
      const double box = (grid.lo(t) - p).cwiseMax(p - grid.hi(t)).cwiseMax(Vec3::Zero()).norm();
      if (box >= nearest) continue;
      const auto& tri = surface[static_cast<std::size_t>(t)];
      const Vec3 a = x.segment<3>(3 * tri[0]), b = x.segment<3>(3 * tri[1]), c = x.segment<3>(3 * tri[2]);
      const Vec3 q = closest_point_on_triangle(p, a, b, c);
      const double d = (p - q).norm();
      if (d < nearest) nearest = d, side = (p - q).dot(faces[static_cast<std::size_t>(t)]) < 0 ? -1.0 : 1.0;
    }
    if (std::isfinite(nearest) && (side < 0 || nearest < reach)) piece.engaged = true;
  }
}

CuttingForce cutting_force(const std::vector<EdgePiece>& pieces, const CuttingMaterial& material) {
  CuttingForce out;
  for (const EdgePiece& piece : pieces) {
    if (!piece.engaged) continue;
    out.engaged_length += piece.length;
    const Vec3 across = piece.motion - piece.motion.dot(piece.tangent) * piece.tangent;
    const double advance = across.norm(), slide = piece.motion.norm();
    // Below a nanometre per step the direction is rounding: the piece is at rest.
    if (advance > 1e-9) {
      out.crack_area += piece.length * advance;
      out.on_tool -= (material.toughness * piece.length / advance) * across;
    }
    if (slide > 1e-9) out.on_tool -= (material.flank_friction * piece.length / slide) * piece.motion;
  }
  return out;
}

double onset_work(double engaged_width, double radius, double advance, double toughness) {
  return toughness * std::max(engaged_width, 2 * radius) * advance;
}

}  // namespace incise::physics
