#include "physics/cut/cutting_resistance.hpp"

#include "physics/core/contact.hpp"
#include "physics/core/nearest_triangles.hpp"

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
                  const std::vector<std::uint8_t>& cut_face, double reach, std::vector<EdgePiece>& pieces,
                  std::vector<int>* hint, Executor& executor) {
  if (pieces.empty()) return;
  // The faces the scan looks at (not a cut face, not degenerate): each piece's nearest, from
  // only the triangles near it (physics/core/nearest_triangles.hpp).
  std::vector<Vec3> points;
  points.reserve(pieces.size());
  for (const EdgePiece& piece : pieces) points.push_back(piece.point);
  const std::vector<NearestTriangle> nearest = nearest_triangles(x, surface, cut_face, points, hint, executor);
  for (std::size_t i = 0; i < pieces.size(); ++i) {
    const NearestTriangle& n = nearest[i];
    if (n.triangle < 0) continue;
    const double side = (pieces[i].point - n.closest).dot(face_normal(x, surface[static_cast<std::size_t>(n.triangle)])) < 0
                            ? -1.0 : 1.0;
    if (side < 0 || n.distance < reach) pieces[i].engaged = true;
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
