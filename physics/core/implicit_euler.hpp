// One linearly implicit (backward) Euler step with the corotation frames frozen
// (Baraff & Witkin 1998, eq. 6 with Rayleigh damping D = alpha M + beta K).
#pragma once

#include <cstdint>
#include <span>
#include <vector>

#include "physics/core/cg.hpp"
#include "physics/core/model.hpp"
#include "physics/core/warm_start.hpp"
#include "physics/solve/rest_factor.hpp"

namespace incise::physics {

struct ImplicitEulerSettings {
  double dt = 1e-3;
  double rayleigh_mass = 0;       // alpha, 1/s
  double rayleigh_stiffness = 0;  // beta, s
  CgSettings cg;
  // Assemble the current system A in 3x3 blocks once per step (DeformableModel::
  // current_stiffness; physics/solve/current_system.hpp) and multiply by it, in CG and in a
  // V-cycle's smoother, instead of the matrix-free product. Off: the models' own products
  // (solver.preconditioner "multigrid_current" turns it on). Models without an assembly or
  // with dashpots or an extra stiffness of their own stay matrix-free.
  bool assembled_system = false;
};

// Whether a step with assembled_system assembles `model`'s current stiffness, and solves on it
// with the current system's V-cycle (given a factor with a smoother): the model offers one and
// has no dashpots nor extra stiffness of its own.
bool assembles_current_stiffness(const DeformableModel& model);

struct StepReport {
  CgResult cg;
  bool nonfinite = false;     // the step was rejected and the State left unchanged
  double elastic_energy = 0;  // of the new state
  double kinetic_energy = 0;  // of the new state
  double assembly_ms = 0;     // assembling the current system (assembled_system)
};

// Solves
//   [(1 + dt alpha) M + (dt beta + dt^2) K] dv
//       = dt [f_elastic(x) + f_ext + f_springs - dt K v - alpha M v - beta K v]
// then v += dv, x += dt v, where K is the model stiffness plus the springs' 3x3 stiffnesses
// (penalty contacts are integrated implicitly for stability). A model with dashpots of its own
// (DeformableModel::has_damping, f = -D v) adds dt D to the matrix and -dt D v to the right.
// A model with an extra stiffness (physics/core/extra_stiffness.hpp: the mass-spring's
// correction forces) adds dt^2 K_extra to the matrix and -dt^2 K_extra v to the right; where it
// is not symmetric the system is solved by Jacobi-preconditioned BiCGSTAB
// (physics/solve/bicgstab.hpp, the CG's settings and report; `rest_factor` unused).
// - Calls model.update_rotations(x) first.
// - `fixed_nodes`: one entry per node, 1 = fixed (empty = none); fixed nodes keep their
//   position and get zero velocity.
// - `external_forces`: 3n (gravity, loads).
// - If anything non-finite arises the State is left unchanged and nonfinite is set.
// - A CG that stops unconverged (max iterations) still advances the state; see report.cg.
// - `warm_start` (optional): CG starts from its combination of the last steps' dv and records
//   this step's (physics/core/warm_start.hpp); as deterministic as a zero start. Left
//   unchanged when the step is rejected.
// - `rest_factor` (optional): CG is preconditioned with it, warped by the model's node
//   rotations (physics/solve/warped_preconditioner.hpp), instead of Jacobi. It may be the
//   factor of an older topology or another dt: any SPD approximation converges, only slower.
StepReport implicit_euler_step(DeformableModel& model, State& state,
                               const std::vector<uint8_t>& fixed_nodes,
                               const Vector& external_forces, std::span<const NodalSpring> springs,
                               const ImplicitEulerSettings& settings,
                               WarmStart* warm_start = nullptr, const RestFactor* rest_factor = nullptr);

// m_i g at every node (3n).
Vector gravity_forces(const Vector& lumped_masses, const Vec3& g);

// 1/2 sum_i m_i |v_i|^2.
double kinetic_energy(const Vector& lumped_masses, const Vector& velocities);

}  // namespace incise::physics
