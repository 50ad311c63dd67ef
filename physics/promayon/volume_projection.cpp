#include "physics/promayon/volume_projection.hpp"

#include <cmath>
#include <limits>
#include <optional>
#include <stdexcept>

namespace incise::physics {

namespace {

Vec3 at(const Vector& x, int i) { return x.segment<3>(3 * i); }

double cubic_value(const VolumeCubic& k, double target, double l) { return ((k.a * l + k.b) * l + k.c) * l + k.d - target; }
double cubic_slope(const VolumeCubic& k, double l) { return (3 * k.a * l + 2 * k.b) * l + k.c; }

// Newton from `start`; nothing when it does not settle.
std::optional<double> newton(const VolumeCubic& k, double target, double start) {
  double l = start;
  for (int it = 0; it < 100; ++it) {
    const double slope = cubic_slope(k, l);
    if (slope == 0 || !std::isfinite(slope)) return std::nullopt;
    const double step = cubic_value(k, target, l) / slope;
    l -= step;
    if (!std::isfinite(l)) return std::nullopt;
    if (std::abs(step) <= 1e-15 * std::max(1.0, std::abs(l))) return l;
  }
  return std::abs(cubic_value(k, target, l)) <= 1e-12 * std::max(std::abs(k.d), std::abs(target)) ? std::optional(l) : std::nullopt;
}

}  // namespace

double closed_volume(const Vector& x, const Triangles& triangles) {
  double v = 0;
  for (const auto& t : triangles) v += at(x, t[0]).dot(at(x, t[1]).cross(at(x, t[2])));
  return v / 6;
}

Vector volume_gradient(const Vector& x, const Triangles& triangles, const std::vector<std::uint8_t>& fixed) {
  Vector g = Vector::Zero(x.size());
  for (const auto& t : triangles)
    for (int k = 0; k < 3; ++k)
      g.segment<3>(3 * t[k]) += at(x, t[(k + 1) % 3]).cross(at(x, t[(k + 2) % 3])) / 6;
  for (std::size_t i = 0; i < fixed.size(); ++i)
    if (fixed[i]) g.segment<3>(3 * static_cast<Eigen::Index>(i)).setZero();
  return g;
}

VolumeCubic volume_cubic(const Vector& x, const Vector& g, const Triangles& triangles) {
  VolumeCubic k;
  for (const auto& t : triangles) {
    const Vec3 p = at(x, t[0]), q = at(x, t[1]), r = at(x, t[2]);
    const Vec3 u = at(g, t[0]), v = at(g, t[1]), w = at(g, t[2]);
    k.d += p.dot(q.cross(r));
    k.c += u.dot(q.cross(r)) + p.dot(v.cross(r)) + p.dot(q.cross(w));
    k.b += p.dot(v.cross(w)) + u.dot(q.cross(w)) + u.dot(v.cross(r));
    k.a += u.dot(v.cross(w));
  }
  k.a /= 6, k.b /= 6, k.c /= 6, k.d /= 6;
  return k;
}

double smallest_root(const VolumeCubic& k, double target) {
  if (!(k.c > 0) || !std::isfinite(k.a + k.b + k.c + k.d))
    throw std::runtime_error("volume projection: no free surface atom to move (or non-finite coefficients)");
  const auto first = newton(k, target, (target - k.d) / k.c);
  if (!first) throw std::runtime_error("volume projection: the cubic in lambda has no root near the linear estimate");
  double best = *first;
  // The other real roots: deflate by (l - first) to a l^2 + e l + f.
  if (k.a != 0) {
    const double e = k.b + k.a * best, f = k.c + e * best;
    const double disc = e * e - 4 * k.a * f;
    if (disc >= 0) {
      const double s = std::sqrt(disc);
      for (double guess : {(-e + s) / (2 * k.a), (-e - s) / (2 * k.a)})
        if (std::abs(guess) < std::abs(best))
          if (auto polished = newton(k, target, guess); polished && std::abs(*polished) < std::abs(best)) best = *polished;
    }
  }
  return best;
}

VolumeProjection project_volume(Vector& x, const Triangles& triangles, const std::vector<std::uint8_t>& fixed,
                                double target) {
  VolumeProjection out;
  const Vector g = volume_gradient(x, triangles, fixed);
  const VolumeCubic k = volume_cubic(x, g, triangles);
  out.volume_before = k.d;
  out.lambda = smallest_root(k, target);
  x += out.lambda * g;
  out.volume_after = closed_volume(x, triangles);
  return out;
}

void add_volume_penalty_forces(const Vector& x, const Triangles& triangles, const std::vector<std::uint8_t>& fixed,
                               double target, double stiffness, Vector& f) {
  const double v = closed_volume(x, triangles);
  f -= stiffness * (v - target) / (target * target) * volume_gradient(x, triangles, fixed);
}

}  // namespace incise::physics
