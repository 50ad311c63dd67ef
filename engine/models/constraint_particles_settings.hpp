// The constraint-particles model's settings block, `constraint_particles` (docs/scenes.md): its
// own file, free of physics/, so that the scene fuzz target (fuzz/fuzz_models.cpp) reads the
// block as the product does.
#pragma once

#include "engine/scene.hpp"
#include "engine/scene_reader.hpp"

#include <optional>
#include <string>

namespace incise::engine {

// Alg. 3.2's energy-based relaxation (physics::relax), the body's `solver.start: "settled"`: the
// body's own step under gravity until the constraints' energy changes by less than `tolerance`
// per step over `calm_steps` steps in a row, at most `max_steps`; `mass_damping` (1/s) is added
// to the body's damping while it relaxes only, so that an undamped body settles too.
struct ConstraintParticlesRelax {
  double tolerance = 1e-9;  // delta, J
  int max_steps = 100000;
  int calm_steps = 100;
  double mass_damping = 0;  // 1/s
};

struct ConstraintParticlesSettings {
  // Dionne's constraint stiffnesses, J (C is dimensionless); 0 leaves that kind out. 500 is the
  // thesis's falling cube (§4.2). With stiffness_per "volume" they are per tet volume (k_D, k_V
  // in Pa) and per area (k_A in N/m): physics::StiffnessScaling.
  double distance_stiffness = 500;
  double area_stiffness = 500;
  double volume_stiffness = 500;
  std::string stiffness_per = "constraint";  // "constraint" (the thesis's) or "volume"
  std::string area_on = "surface";  // "surface" or "every_face" (the cube's 5,504 triangles)
  std::string damping = "relative";  // "relative" (eq. 1.14) or "constraint" (eq. 1.16)
  double damping_coefficient = 0;    // N s/m (relative) or J s (constraint)
  // "velocity_verlet" (the thesis's choice), "explicit_euler", "rk2", "rk4", "verlet", or
  // "implicit_euler" (the shared implicit step with the Gauss-Newton stiffness; no limiter).
  std::string integrator = "velocity_verlet";
  double stretch_stiffness = 0.1;  // k_E in [0, 1]; 0: no stretch limiter
  double stretch_alpha = 1.05;     // active beyond alpha D0
  int stretch_iterations = 1;      // n, with k' = 1 - (1 - k_E)^(1/n)
  std::optional<double> floor_z;   // particles stay above the plane z = floor_z (explicit integrators)
  ConstraintParticlesRelax relax;  // the settled start's relaxation
};

// Reads the block into body.settings (a ConstraintParticlesSettings).
void read_constraint_particles_settings(Reader& block, BodySpec& body);

}  // namespace incise::engine
