// Explicit time integrators for a DeformableModel: forces only, no linear solve.
//
// The schemes of Dionne's thesis (seed 000, digest seed-000-003.md A.1.5), which its
// integrator benchmark (D1) compares:
//   explicit Euler   (eq. 1.20)  y+ = y + dt f(y) on y = (x, v), both from the old state;
//   RK2, midpoint    (1.21-1.22) y+ = y + dt f(y + dt/2 f(y));
//   RK4, classical   (1.23-1.24);
//   Stoermer Verlet  (1.26-1.27) x+ = 2x - x- + dt^2 a, velocity by central difference;
//   velocity Verlet  (1.28)      x+ = x + dt v + dt^2/2 a, v+ = v + dt/2 (a + a+).
//
// The acceleration of node i is a_i = (f_elastic(x) + f_external)_i / m_i - alpha v_i: lumped
// mass, Rayleigh mass damping alpha (the dashpot k_d = alpha m of the D1 oscillator). The
// corotation frames are recomputed at every force evaluation (model.update_rotations at the
// stage positions), so every stage sees the full nonlinear corotational force.
//
// Common rules, as for implicit_euler_step:
// - `fixed_nodes`: one entry per node, 1 = fixed (empty = none); fixed nodes keep their
//   position bitwise and get zero velocity.
// - `external_forces`: 3n (gravity, loads), held constant over the step.
// - If a non-finite value arises, the State (and the history) are left unchanged and the
//   report's nonfinite flag is set; the caller decides (the engine halves dt and retries).
// - Inconsistent sizes or a non-positive dt throw std::invalid_argument.
// These schemes are only conditionally stable: dt must stay below about 2 / omega_max (RK4
// 2.83 / omega_max, explicit Euler never for undamped oscillation), omega_max the highest
// natural frequency of the body, which for a stiff or nearly incompressible material is
// far below the step sizes of an interactive simulation.
#pragma once

#include <cstdint>
#include <optional>
#include <string_view>
#include <vector>

#include "physics/core/model.hpp"

namespace incise::physics {

enum class ExplicitScheme { explicit_euler, midpoint, runge_kutta4, verlet, velocity_verlet };

// The names used in reports and on the command line: explicit_euler, rk2, rk4, verlet,
// velocity_verlet.
std::string_view explicit_scheme_name(ExplicitScheme scheme);
std::optional<ExplicitScheme> explicit_scheme_from_name(std::string_view name);

struct ExplicitSettings {
  double dt = 1e-3;
  double rayleigh_mass = 0;  // alpha, 1/s: damping force -alpha M v
  // Also the model's own dashpots, -D v (DeformableModel::has_damping), with D frozen at each
  // stage's positions. Off by default, so that the schemes' arithmetic for the models that
  // have dashpots (the mass-spring's) stays as it was; constraint particles turn it on.
  bool model_damping = false;
};

struct ExplicitStepReport {
  bool nonfinite = false;      // the step was rejected and the State left unchanged
  int force_evaluations = 0;   // calls of add_elastic_forces (the cost of the step)
  double elastic_energy = 0;   // of the new state
  double kinetic_energy = 0;   // of the new state's velocities (see verlet_step)
};

// Stoermer Verlet's memory: the positions one step back, x(t - dt), and the dt they were
// taken with. An empty history (or one taken with another dt) starts the scheme from the
// second-order Taylor expansion x(t - dt) = x - dt v + dt^2/2 a(x, v). Dionne's thesis starts
// from rest with x(-dt) = x(0) (its v(0) = a(0) = 0); to reproduce that, set
// previous_positions = positions and time_step = dt before the first step.
struct VerletHistory {
  Vector previous_positions;
  double time_step = 0;
};

ExplicitStepReport explicit_euler_step(DeformableModel& model, State& state,
                                       const std::vector<uint8_t>& fixed_nodes,
                                       const Vector& external_forces,
                                       const ExplicitSettings& settings);

// RK2 in its midpoint form, the one Dionne used (for linear forces Heun's form gives the same
// steps, so the D1 limits do not tell them apart).
ExplicitStepReport midpoint_step(DeformableModel& model, State& state,
                                 const std::vector<uint8_t>& fixed_nodes,
                                 const Vector& external_forces, const ExplicitSettings& settings);

ExplicitStepReport runge_kutta4_step(DeformableModel& model, State& state,
                                     const std::vector<uint8_t>& fixed_nodes,
                                     const Vector& external_forces,
                                     const ExplicitSettings& settings);

// Stoermer (position) Verlet, eq. 1.26: x(t + dt) = 2 x(t) - x(t - dt) + dt^2 a(x(t), v).
// The velocity is the central difference (eq. 1.27) v(t) = (x(t + dt) - x(t - dt)) / (2 dt),
// known only after the step: the State's velocities therefore lag its positions by one step,
// and the damping force uses the lagged velocity (the "one step late" of the thesis, which
// makes the damped scheme first order). One force evaluation per step.
ExplicitStepReport verlet_step(DeformableModel& model, State& state,
                               const std::vector<uint8_t>& fixed_nodes,
                               const Vector& external_forces, const ExplicitSettings& settings,
                               VerletHistory& history);

// Velocity Verlet, eq. 1.28, with a(t) evaluated at the start of every step (two force
// evaluations per step, as in the thesis; no state beyond x and v). The damping part of
// a(t + dt) needs v(t + dt): it uses the explicit Euler prediction v + dt a(t), which keeps
// the damped scheme second order (with v(t) instead it drops to first order).
ExplicitStepReport velocity_verlet_step(DeformableModel& model, State& state,
                                        const std::vector<uint8_t>& fixed_nodes,
                                        const Vector& external_forces,
                                        const ExplicitSettings& settings);

// Dispatches on `scheme`; `history` is required for ExplicitScheme::verlet (throws
// std::invalid_argument if null) and ignored otherwise. A dt beyond the model's
// explicit_step_limit() is refused (std::invalid_argument with both numbers). The schemes see
// the elastic forces and Rayleigh mass damping, and a model's own dashpots only where
// settings.model_damping asks for them.
ExplicitStepReport explicit_step(ExplicitScheme scheme, DeformableModel& model, State& state,
                                 const std::vector<uint8_t>& fixed_nodes,
                                 const Vector& external_forces, const ExplicitSettings& settings,
                                 VerletHistory* history = nullptr);

}  // namespace incise::physics
