// FrontSurface's geometric tests (front_surface.hpp): the stroke's points by id and the
// orientation predicates on them, evaluated in a canonical order so that every test sharing
// four points sees the same sign (front_surface.hpp says why). Inline: the crossing searches
// call them for every candidate edge and triangle.
#pragma once

#include "physics/core/model.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstddef>
#include <optional>
#include <utility>
#include <vector>

namespace incise::physics::front {

inline bool finite(const Vec3& v) { return std::isfinite(v.x()) && std::isfinite(v.y()) && std::isfinite(v.z()); }

// The sign of an orientation, evaluated on the points in increasing id order and fixed up by
// the permutation's parity, zero counted as positive: every test that shares the four points
// sees the same sign (see front_surface.hpp). `value` is the determinant in the caller's order.
struct Orientation {
  double value = 0;
  int sign = 1;
};

// The stroke's points: the base mesh's vertices, then the sheet's (blade point i of sample j
// at base + j * points + i).
struct PointTable {
  const std::vector<Vec3>* base = nullptr;
  const std::vector<std::vector<Vec3>>* samples = nullptr;
  int points_per_sample = 0;
  int base_count() const { return static_cast<int>(base->size()); }
  int sheet_id(int point, int sample) const { return base_count() + sample * points_per_sample + point; }
  const Vec3& operator[](int id) const {
    if (id < base_count()) return (*base)[static_cast<size_t>(id)];
    const int local = id - base_count();
    return (*samples)[static_cast<size_t>(local / points_per_sample)][static_cast<size_t>(local % points_per_sample)];
  }
};

inline Orientation orient(const PointTable& points, int a, int b, int c, int d) {
  std::array<int, 4> ids{a, b, c, d};
  int parity = 1;
  for (int i = 0; i < 4; ++i)
    for (int j = 0; j + 1 < 4 - i; ++j)
      if (ids[static_cast<size_t>(j)] > ids[static_cast<size_t>(j + 1)]) {
        std::swap(ids[static_cast<size_t>(j)], ids[static_cast<size_t>(j + 1)]);
        parity = -parity;
      }
  const Vec3& p = points[ids[0]];
  const double det = (points[ids[1]] - p).dot((points[ids[2]] - p).cross(points[ids[3]] - p));
  return {parity * det, parity * (det >= 0 ? 1 : -1)};
}

// Segment [p, q] against triangle (x, y, z), all ids. `along`: the crossing's fraction from p;
// `weights`: its barycentric coordinates on x, y, z; `p_sign`: orient(p, x, y, z)'s sign
// (positive: p is on the side opposite the triangle's normal).
struct Crossing {
  double along = 0;
  std::array<double, 3> weights{};
  int p_sign = 0;
};

inline std::optional<Crossing> segment_crosses(const PointTable& points, int p, int q, int x, int y, int z) {
  const Orientation sp = orient(points, p, x, y, z), sq = orient(points, q, x, y, z);
  if (sp.sign == sq.sign) return std::nullopt;
  const Orientation e_xy = orient(points, p, q, x, y), e_yz = orient(points, p, q, y, z),
                    e_zx = orient(points, p, q, z, x);
  if (e_xy.sign != e_yz.sign || e_yz.sign != e_zx.sign) return std::nullopt;
  Crossing hit;
  const double denominator = sp.value - sq.value;
  hit.along = denominator != 0 ? std::clamp(sp.value / denominator, 0.0, 1.0) : 0.5;
  const double total = e_xy.value + e_yz.value + e_zx.value;
  if (total != 0)
    hit.weights = {e_yz.value / total, e_zx.value / total, e_xy.value / total};
  else
    hit.weights = {1.0 / 3, 1.0 / 3, 1.0 / 3};
  hit.p_sign = sp.sign;
  return hit;
}

// Whether the segment [p, q] crosses triangle (a, b, c) (Moller-Trumbore), for the parity of
// a ray: only the "began inside" report rests on it.
inline int ray_crosses(const Vec3& p, const Vec3& q, const Vec3& a, const Vec3& b, const Vec3& c) {
  const Vec3 direction = q - p, e1 = b - a, e2 = c - a;
  const Vec3 h = direction.cross(e2);
  const double determinant = e1.dot(h);
  if (determinant == 0) return 0;
  const double inverse = 1 / determinant;
  const Vec3 s = p - a;
  const double u = inverse * s.dot(h);
  if (u < 0 || u > 1) return 0;
  const Vec3 k = s.cross(e1);
  const double v = inverse * direction.dot(k);
  if (v < 0 || u + v > 1) return 0;
  const double along = inverse * e2.dot(k);
  return along >= 0 && along <= 1 ? 1 : 0;
}

}  // namespace incise::physics::front
