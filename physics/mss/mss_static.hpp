// Static equilibria of the Baudet mass-spring model and the test harness of Fléchon's report
// (seed 003; digest seed-000-003.md C.2, "Test harness utilities"): the nonlinear static
// solve behind the comparisons with FEM (D6 elongation, D8 bending, `incise bench accuracy`)
// and the linear traction test that measures a spring network's E and nu (D5, D9).
#pragma once

#include "physics/core/model.hpp"
#include "physics/mss/hex_mass_spring.hpp"

#include <Eigen/Dense>

#include <array>
#include <cstdint>
#include <vector>

namespace incise::physics {

struct MassSpringStatic {
  Vector positions;   // 3n, at equilibrium
  int iterations = 0;  // Newton iterations, all increments together
  double residual = 0;  // |f| on the free dofs at the end over |f| on them at the first iterate
  bool converged = false;
};

// The network's equilibrium with the nodes `fixed` moved by `prescribed` (3n, read there;
// empty: held at rest) under the nodal forces `load` (3n or empty), the springs' full nonlinear
// forces and, when the model has them, Baudet's corrections. Newton with the springs' tangent
// (sparse LDLT) plus, with corrections, their derivative brick by brick (the model's
// correction_tangents, central differences; non-symmetric: sparse LU). The prescribed motion and
// the load are applied in `increments` equal steps, each iterated until the update is below
// `tolerance` x the largest displacement. The tangent is the current one, whose transverse
// spring terms (1 - L0 / L) carry the network's near-mechanisms: at rest they vanish, and a
// rest-tangent iteration on a voxelised beam crawls (50-90 iterations) or diverges. Throws
// std::runtime_error when the tangent cannot be factorised or an increment does not converge
// in 200 iterations.
MassSpringStatic solve_mass_spring_static(HexMassSpring& model, const std::vector<uint8_t>& fixed,
                                          const Vector& prescribed, const Vector& load, int increments = 1,
                                          double tolerance = 1e-10);

// The network's stiffness at rest as a dense matrix (small meshes only): the springs' K, minus
// the derivative of the correction forces when the model has them (central differences: they
// vanish at rest and are linear in a small displacement).
Eigen::MatrixXd mass_spring_rest_stiffness(HexMassSpring& model);

// The dense stiffness at rest of a network of linear springs (a, b, k) over the nodes `rest`.
Eigen::MatrixXd spring_network_stiffness(const Vector& rest, const std::vector<Spring>& springs);

struct TractionMeasure {
  double youngs_modulus = 0;
  double poisson_ratio = 0;
};

// Linear traction along x of the box [0, size] gridded by `cells` (its nodes `rest`, all on the
// grid) with stiffness `k` at rest (digest B.1.3's check, Fléchon's displacement test): the face
// x = 0 held along x only (rollers) and three of its lateral dofs holding the rigid motions
// without restraining the contraction, the face x = size.x pulled by a total force shared by the
// consistent weights (corner 1/4, edge 1/2, interior 1 per face cell, Fléchon Fig. 9). E from the
// loaded face's mean stretch, nu from the mean contraction of the faces y = 0 and y = size.y.
TractionMeasure measure_traction(const Eigen::MatrixXd& k, const Vector& rest, const Vec3& size,
                                 const std::array<int, 3>& cells);

// The digest's %e_dm and %e_max (B.3, after Natsupakpong 2010): the RMS and the largest
// distance between two sets of node positions, in % of o_max, the largest displacement of the
// reference from `rest`.
struct PositionError {
  double rms_pct = 0;  // %e_dm
  double max_pct = 0;  // %e_max
  double reference_max = 0;  // o_max, m
};
PositionError position_error(const Vector& rest, const Vector& reference, const Vector& positions);

}  // namespace incise::physics
