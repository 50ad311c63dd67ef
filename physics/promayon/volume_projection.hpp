// Exact volume control of a closed triangulated surface by one projection along the volume
// gradient (Promayon 1997; seed 002 §1.5, with the constants of §9.1 corrected):
//   V(x) = 1/6 sum_faces x_a . (x_b x x_c),  g_i = dV/dx_i = 1/6 sum_{faces at i} x_b x x_c
// (the printed eq. 6 has V = 1/3 sum X_i.A_i and grad_i = A_i: with its A_i, V is 1/9 of the sum
// and the gradient A_i / 3; the direction is all the projection uses). The corrected positions
// x + lambda g satisfy V(x + lambda g) = V0 (eq. 8's V(X^) = V0 is a typo, §9.2); V being cubic in
// the positions, that is a lambda^3 + b lambda^2 + c lambda + d - V0 = 0 with per-face sums
//   d = 1/6 p.(q x r),  c = 1/6 [u.(q x r) + p.(v x r) + p.(q x w)],
//   b = 1/6 [p.(v x w) + u.(q x w) + u.(v x r)],  a = 1/6 u.(v x w),
// (p, q, r) a face's positions and (u, v, w) their gradients. The root taken is the real root
// of smallest |lambda| (§9.11: "the smallest real root" read as the one nearest the linear
// estimate (V0 - d) / c), so the surface moves as little as possible.
//
// Fixed atoms get no gradient, so they stay where the boundary conditions put them (the
// projection is exact all the same: the cubic is built from the gradient used).
#pragma once

#include "physics/core/model.hpp"

#include <array>
#include <cstdint>
#include <vector>

namespace incise::physics {

using Triangles = std::vector<std::array<int, 3>>;

// The enclosed volume of a closed, outward-oriented triangulated surface, m^3.
double closed_volume(const Vector& x, const Triangles& triangles);

// g (3n): the volume's gradient, zero at fixed atoms (fixed empty: none) and off the surface.
Vector volume_gradient(const Vector& x, const Triangles& triangles, const std::vector<std::uint8_t>& fixed);

struct VolumeCubic {
  double a = 0, b = 0, c = 0, d = 0;  // V(x + lambda g) = a l^3 + b l^2 + c l + d
};
VolumeCubic volume_cubic(const Vector& x, const Vector& gradient, const Triangles& triangles);

// The real root of a l^3 + b l^2 + c l + (d - target) nearest zero. Throws std::runtime_error
// when there is none (c = 0: no free surface atom) or a non-finite value arises.
double smallest_root(const VolumeCubic& cubic, double target);

struct VolumeProjection {
  double lambda = 0;
  double volume_before = 0;
  double volume_after = 0;  // recomputed from the moved positions
};

// Moves x by lambda g so that the volume is `target`.
VolumeProjection project_volume(Vector& x, const Triangles& triangles, const std::vector<std::uint8_t>& fixed,
                                double target);

// The soft variant: f_i += -k_V (V - V0) / V0^2 g_i (§1.5's penalty, C_V = (V - V0) / V0).
void add_volume_penalty_forces(const Vector& x, const Triangles& triangles, const std::vector<std::uint8_t>& fixed,
                               double target, double stiffness, Vector& f);

}  // namespace incise::physics
