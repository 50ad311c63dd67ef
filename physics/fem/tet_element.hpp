// Element-level formulas shared by the corotational model and the static solver.
#pragma once

#include <Eigen/LU>
#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <string>

#include "physics/core/model.hpp"

namespace incise::physics {

struct TetRestGeometry {
  Mat3 inverse_shape;  // Dm^-1, Dm = [X1 - X0, X2 - X0, X3 - X0]; row a - 1 is grad N_a
  double volume = 0;   // det(Dm) / 6
};

// Throws std::invalid_argument naming `element` if the tet is inverted (det Dm < 0) or
// degenerate (|det Dm| tiny against the cube of its longest edge, or not finite).
inline TetRestGeometry tet_rest_geometry(const Vec3& x0, const Vec3& x1, const Vec3& x2,
                                         const Vec3& x3, long long element) {
  Mat3 shape;
  shape << x1 - x0, x2 - x0, x3 - x0;
  const double determinant = shape.determinant();
  double longest = std::max({shape.col(0).norm(), shape.col(1).norm(), shape.col(2).norm(),
                             (x2 - x1).norm(), (x3 - x1).norm(), (x3 - x2).norm()});
  // A regular tet has det / longest^3 = 1/sqrt(2); 1e-10 only rejects slivers that would make
  // the stiffness meaningless.
  if (!std::isfinite(determinant) || !(longest > 0) ||
      std::abs(determinant) <= 1e-10 * longest * longest * longest) {
    throw std::invalid_argument("tet element " + std::to_string(element) +
                                " is degenerate (rest volume " + std::to_string(determinant / 6) +
                                ")");
  }
  if (determinant < 0) {
    throw std::invalid_argument(
        "tet element " + std::to_string(element) + " is inverted in the rest shape (volume " +
        std::to_string(determinant / 6) + "); corners must satisfy det[X1-X0, X2-X0, X3-X0] > 0");
  }
  return {shape.inverse(), determinant / 6.0};
}

// Block (a, b) of the isotropic linear elastic stiffness density for shape-function gradients
// g_a, g_b: from W = lambda/2 (div u)^2 + mu eps:eps with u = sum_b N_b u_b,
//   K_ab = lambda g_a g_b^T + mu g_b g_a^T + mu (g_a . g_b) I.
inline Mat3 isotropic_stiffness_block(const Vec3& gradient_a, const Vec3& gradient_b, double lambda,
                                      double mu) {
  return lambda * gradient_a * gradient_b.transpose() + mu * gradient_b * gradient_a.transpose() +
         mu * gradient_a.dot(gradient_b) * Mat3::Identity();
}

}  // namespace incise::physics
