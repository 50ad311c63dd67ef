// The quartic spline weight of the moving least squares shape functions (Magnoux 2020,
// eq. 4.7). The thesis prints the r^3 coefficient as 1; it must be 8 (seed-004 §1.4): only then
// does w vanish at r = h and integrate to 1 over the ball of radius h.
#pragma once

#include <numbers>

namespace incise::physics {

// w(r) = 105 / (16 pi h^3) (1 - 6 q^2 + 8 q^3 - 3 q^4) = 105 / (16 pi h^3) (1 - q)^3 (1 + 3 q),
// q = r / h, zero for q >= 1. The factored form is used because it stays accurate near q = 1,
// where the expanded polynomial cancels.
inline double quartic_spline(double distance, double support) {
  const double q = distance / support;
  if (!(q < 1.0)) return 0.0;
  const double complement = 1.0 - q;
  return 105.0 / (16.0 * std::numbers::pi * support * support * support) * complement *
         complement * complement * (1.0 + 3.0 * q);
}

// dw/dr = -315 / (4 pi h^4) q (1 - q)^2, zero for q >= 1 (and at r = 0, so the gradient
// (dw/dr) (x - x_i) / r has no singularity there).
inline double quartic_spline_derivative(double distance, double support) {
  const double q = distance / support;
  if (!(q < 1.0)) return 0.0;
  const double complement = 1.0 - q;
  return -315.0 / (4.0 * std::numbers::pi * support * support * support * support) * q *
         complement * complement;
}

}  // namespace incise::physics
