// One step of Dionne's soft-tissue physics (seed 000, Alg. 3.2; digest A.1.4-A.1.6, C.1): an
// explicit integrator over the constraint forces and the damping (velocity Verlet by default,
// the thesis's choice, §4.1), then the position-based stretch limiter on the new positions q,
// then the velocity of every projected particle recomputed as (q - x) / dt, the others keeping
// the integrator's. An optional floor (the plane z = floor_z of the cube test, §4.2) stops
// particles from passing below it: the position is put back on the plane and a downward
// velocity dropped (an inelastic, frictionless contact; the thesis does not say how its plane
// acts).
#pragma once

#include "physics/core/explicit_integrators.hpp"
#include "physics/cp/constraint_particles.hpp"

#include <cstdint>
#include <optional>
#include <vector>

namespace incise::physics {

// The stretch constraint (eq. 3.9-3.10): an edge longer than alpha D0 is shortened towards
// alpha D0 by k' (|x_i - x_j| - alpha D0), split by the inverse masses; k' = 1 - (1 - k_E)^(1/n)
// over n iterations (eq. 1.40) so that its effect does not depend on n.
struct StretchLimiter {
  bool enabled = true;
  double stiffness = 0.1;  // k_E in [0, 1] (§4.2: kept <= 0.1 so that the forces drive the motion)
  double alpha = 1.05;     // the threshold alpha D0 (Table 4.8's "0.05" is the 5 % over D0)
  int iterations = 1;      // n
};

struct CpStepSettings {
  ExplicitScheme scheme = ExplicitScheme::velocity_verlet;
  double dt = 1e-3;
  double rayleigh_mass = 0;  // 1/s, the scene's Rayleigh alpha, on top of the model's own damping
  StretchLimiter limiter;
  std::optional<double> floor_z;
};

struct StretchReport {
  int projections = 0;  // edge projections applied, summed over the iterations
  int particles = 0;    // distinct particles moved
};

struct CpStepReport {
  ExplicitStepReport integrator;
  StretchReport stretch;
  int floor_contacts = 0;  // particles put back on the floor
  int inverted_tets = 0;   // after the step
  bool nonfinite = false;  // the step was rejected, the state left unchanged
};

// Projects q in place; `w` the inverse masses (0: fixed, never moved). `moved` (one entry per
// particle) gets 1 for each particle a projection moved. Every projection moves its two
// particles by -w_i s and +w_j s: sum m dx = 0 whenever both are free (eq. 3.15).
StretchReport limit_stretch(const std::vector<StretchEdge>& edges, const Vector& w, const StretchLimiter& limiter,
                            Vector& q, std::vector<std::uint8_t>& moved);

// Inverse masses: 1/m, 0 on the fixed particles.
Vector inverse_masses(const Vector& masses, const std::vector<std::uint8_t>& fixed);

// The step; `history` is Stoermer Verlet's (ignored by the other schemes). Throws
// std::invalid_argument as explicit_step does.
CpStepReport constraint_particles_step(ConstraintParticles& model, State& state, const std::vector<std::uint8_t>& fixed,
                                       const Vector& external, const CpStepSettings& settings, VerletHistory& history);

// Alg. 3.2's relaxation to a "stable" state, for quasi-static targets (the post-operative
// shape): steps until the constraints' energy changes by less than `tolerance` over one step
// (|E_t - E_prev| < delta; the thesis gives no delta), or `max_steps`. Taken literally the test
// stops at the first step of a body starting at rest (its energy barely moves yet) or at any
// turning point, so it must hold over `calm_steps` steps in a row (ours). The body needs damping
// to settle.
struct RelaxSettings {
  double tolerance = 1e-9;  // delta, J
  int max_steps = 100000;
  int calm_steps = 100;
};

struct RelaxReport {
  int steps = 0;
  double energy = 0;       // the constraints' energy at the end, J
  bool converged = false;  // |dE| < tolerance before max_steps
  bool nonfinite = false;
};

RelaxReport relax(ConstraintParticles& model, State& state, const std::vector<std::uint8_t>& fixed, const Vector& external,
                  const CpStepSettings& settings, const RelaxSettings& relax_settings);

}  // namespace incise::physics
