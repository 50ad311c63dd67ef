// Dionne's normalised physical constraints (seed 000, digest seed-000-003.md A.1.3): each is a
// scalar C of 2, 3 or 4 particles, zero at its rest measure, whose energy is E = k C^2 / 2 and
// whose force on particle a is f_a = -k C dC/dx_a (eq. 1.9). The gradients of one constraint sum
// to zero and have no moment about any point (C is invariant under translation and rotation),
// so each constraint's forces conserve momentum and angular momentum (eq. 3.14).
#pragma once

#include "physics/core/model.hpp"

#include <array>

namespace incise::physics {

enum class ConstraintKind { distance, area, volume };

struct Constraint {
  ConstraintKind kind = ConstraintKind::distance;
  std::array<int, 4> nodes{};  // the first 2 (distance), 3 (area) or 4 (volume) are used
  double rest = 0;             // D0, A0 or V0 (signed, > 0 for a positively oriented tet)
  double stiffness = 0;        // k, an energy (J): C is dimensionless
};

// How many particles a constraint of this kind joins.
constexpr int constraint_arity(ConstraintKind kind) {
  return kind == ConstraintKind::distance ? 2 : kind == ConstraintKind::area ? 3 : 4;
}

// The constraint's measure at x: distance, area, or signed volume U / 6.
double constraint_measure(const Constraint& c, const Vector& x);

// C(x) and its gradients dC/dx_a for the constraint's particles a = 0 .. arity - 1.
//   distance C = (|x_j - x_i| - D0) / D0                 (eq. 3.1)
//   area     C = (|u| / 2 - A0) / A0, u = x_ij x x_ik     (eq. 3.3; gradients of A.27, not the
//                                                          mistyped A.25/A.26)
//   volume   C = (U / 6 - V0) / V0, U = x_ij . (x_ik x x_il) (eq. 3.6; gradients w / (6 V0))
// A degenerate configuration (coincident particles, a zero-area triangle) has a zero gradient.
double constraint_gradient(const Constraint& c, const Vector& x, std::array<Vec3, 4>& gradient);

}  // namespace incise::physics
