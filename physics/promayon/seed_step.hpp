// The explicit step of Promayon's models in the seed's order (seed 002 §1.9; E.6 Alg. 1,
// E.5 §2.2.5, E.4 §3.1):
//   1. boundary conditions: fixed atoms get zero velocity;
//   2. forces: the model's elastic forces, whose reactions the model redistributes to the
//      neighbours itself (shape_memory.hpp), plus the external and contact forces, the
//      damping -k_a v of every atom, a model's own dashpots and the volume penalty if asked;
//   3. integrate: explicit Euler (x+ = x + dt v, v+ = v + dt a, both from the old state, the
//      scheme of the seed's stability analysis, §1.3) or its symplectic form (v first, then x
//      with the new v);
//   4. local constraints: fixed atoms back where they were;
//   5. the global volume constraint: the exact projection (volume_projection.hpp) onto V0(t);
//   6. velocity correction: each atom's velocity gains the displacement the constraints
//      imposed, divided by dt (§1.9 [interp.]: the seed gives no formula; adding the imposed
//      displacement keeps the integrated velocity, where v = (x+ - x)/dt would discard it
//      under forward Euler).
#pragma once

#include "physics/core/model.hpp"
#include "physics/promayon/volume_projection.hpp"

#include <cstdint>
#include <optional>
#include <string_view>
#include <utility>
#include <vector>

namespace incise::physics {

enum class SeedScheme { explicit_euler, symplectic_euler };
std::string_view seed_scheme_name(SeedScheme s);
std::optional<SeedScheme> seed_scheme_from_name(std::string_view name);

enum class VolumeMode { exact, penalty };

// The volume a closed surface must keep: V0(t), the rest volume when no event is given, else
// linear between events, the first and last held (the scene's loads' convention).
struct VolumeControl {
  Triangles triangles;
  VolumeMode mode = VolumeMode::exact;
  double penalty_stiffness = 0;  // k_V, N m (penalty mode)
  double rest_volume = 0;        // m^3
  std::vector<std::pair<double, double>> target;  // (time s, V0 m^3), increasing times
  double at(double time) const;
};

struct SeedStepSettings {
  double dt = 1e-3;
  double damping = 0;       // k_a, N s/m on every atom (the seed's -k_a v)
  double mass_damping = 0;  // alpha, 1/s: -alpha m_i v_i besides (the same rate on light and heavy atoms)
  SeedScheme scheme = SeedScheme::explicit_euler;
};

struct SeedStepReport {
  bool nonfinite = false;        // rejected: the state is unchanged
  double volume_target = 0;      // V0 at the step's end (volume control only)
  double volume = 0;             // the closed surface's volume after the step
  double lambda = 0;             // the projection's multiplier
  double elastic_energy = 0, kinetic_energy = 0;
};

// One step of dt ending at `end_time` (for V0(t)). `fixed`: one entry per atom (empty: none);
// `external`: 3n; `springs`: point forces (contact), applied explicitly; `volume`: null for
// none. A volume projection that finds no root or any non-finite value rejects the step.
SeedStepReport seed_explicit_step(DeformableModel& model, State& state, const std::vector<std::uint8_t>& fixed,
                                  const Vector& external, const std::vector<NodalSpring>& springs,
                                  const SeedStepSettings& settings, const VolumeControl* volume, double end_time);

// The largest dt of the symplectic Euler step without damping, 2 / omega_max, omega_max^2 the
// largest eigenvalue of M^-1 K over the free atoms (K the model's stiffness at rest), by power
// iteration (which approaches it from below: the estimate errs towards large dt by the last
// iterate's gap). Forward Euler is not bounded by it (it needs damping, §1.3).
double seed_step_limit(DeformableModel& model, const std::vector<std::uint8_t>& fixed);

// Steps 4-6 alone, for a state another integrator advanced from `before` (the implicit Euler
// option): fixed atoms restored, the volume projected, the velocities corrected. Returns false
// (state untouched) when the projection fails or gives non-finite values.
bool apply_seed_constraints(State& state, const Vector& before_positions, const std::vector<std::uint8_t>& fixed,
                            double dt, const VolumeControl* volume, double end_time, SeedStepReport& report);

}  // namespace incise::physics
