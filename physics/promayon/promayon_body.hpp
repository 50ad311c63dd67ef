// A body of Promayon's discrete models as the engine steps it: the force model (ShapeMemory or
// SpringNetwork), the closed surface whose volume it may control, and the seed's step
// (seed_step.hpp), which the engine calls instead of its implicit Euler (engine/solve.cpp).
// Every DeformableModel query is the force model's.
//
// Two integrators: the seed's explicit step (the default, `substeps` of it per engine step of
// dt) or the engine's implicit Euler followed by the seed's steps 4-6 (fixed atoms, volume
// projection, velocity correction). The implicit one uses the force model's K: the exact
// tangent of the spring network, the frozen-normal Jacobian of the shape memory.
#pragma once

#include "physics/core/implicit_euler.hpp"
#include "physics/promayon/seed_step.hpp"

#include <memory>
#include <optional>
#include <vector>

namespace incise::physics {

struct PromayonStepping {
  bool implicit = false;   // implicit Euler + steps 4-6 instead of the seed's explicit step
  int substeps = 1;        // explicit steps per engine step
  double damping = 0;      // k_a, N s/m per atom (explicit; the implicit one uses the scene's Rayleigh damping)
  double mass_damping = 0; // alpha, 1/s: -alpha m v per atom (explicit)
  SeedScheme scheme = SeedScheme::symplectic_euler;
};

class PromayonBody final : public DeformableModel {
 public:
  PromayonBody(std::unique_ptr<DeformableModel> forces, const PromayonStepping& stepping,
               std::optional<VolumeControl> volume);
  PromayonBody(const PromayonBody& other);

  int node_count() const override { return forces_->node_count(); }
  const Vector& rest_positions() const override { return forces_->rest_positions(); }
  const Vector& lumped_masses() const override { return forces_->lumped_masses(); }
  void update_rotations(const Vector& x) override { forces_->update_rotations(x); }
  void add_elastic_forces(const Vector& x, Vector& f) const override;
  void add_stiffness_product(const Vector& p, Vector& out) const override { forces_->add_stiffness_product(p, out); }
  void add_stiffness_diagonal(Vector& diag) const override { forces_->add_stiffness_diagonal(diag); }
  double elastic_energy(const Vector& x) const override { return forces_->elastic_energy(x); }
  bool has_damping() const override { return forces_->has_damping(); }
  void add_damping_product(const Vector& p, Vector& out) const override { forces_->add_damping_product(p, out); }
  void add_damping_diagonal(Vector& diag) const override { forces_->add_damping_diagonal(diag); }
  double node_spacing() const override { return forces_->node_spacing(); }
  std::unique_ptr<DeformableModel> clone() const override { return std::make_unique<PromayonBody>(*this); }

  // One engine step of settings.dt from `start_time` (for V0(t)). nonfinite: rejected, the state
  // unchanged. The report's CG is marked converged (an explicit step solves nothing).
  StepReport step(State& state, const std::vector<std::uint8_t>& fixed, const Vector& external,
                  const std::vector<NodalSpring>& springs, const ImplicitEulerSettings& settings, double start_time);

  const DeformableModel& forces() const { return *forces_; }
  const std::optional<VolumeControl>& volume() const { return volume_; }
  // The end of the last accepted step (the penalty's V0 is taken there).
  double time() const { return time_; }
  // The largest |V - V0(t)| / V0(t) after any accepted step so far (exact volume control).
  double worst_volume_error() const { return worst_volume_error_; }
  // The last accepted step's volume and target (0 without volume control).
  double last_volume() const { return last_.volume; }
  double last_volume_target() const { return last_.volume_target; }

 private:
  std::unique_ptr<DeformableModel> forces_;
  PromayonStepping stepping_;
  std::optional<VolumeControl> volume_;
  double time_ = 0;
  double worst_volume_error_ = 0;
  SeedStepReport last_;
};

}  // namespace incise::physics
