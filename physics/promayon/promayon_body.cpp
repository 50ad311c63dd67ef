#include "physics/promayon/promayon_body.hpp"

#include <algorithm>
#include <cmath>
#include <stdexcept>

namespace incise::physics {

PromayonBody::PromayonBody(std::unique_ptr<DeformableModel> forces, const PromayonStepping& stepping,
                           std::optional<VolumeControl> volume)
    : forces_(std::move(forces)), stepping_(stepping), volume_(std::move(volume)) {
  if (!forces_) throw std::invalid_argument("PromayonBody: no force model");
  if (stepping_.substeps < 1) throw std::invalid_argument("PromayonBody: substeps must be >= 1");
}

PromayonBody::PromayonBody(const PromayonBody& other)
    : forces_(other.forces_->clone()),
      stepping_(other.stepping_),
      volume_(other.volume_),
      time_(other.time_),
      worst_volume_error_(other.worst_volume_error_),
      last_(other.last_) {}

void PromayonBody::add_elastic_forces(const Vector& x, Vector& f) const {
  forces_->add_elastic_forces(x, f);
  // The penalty variant is a force like the others, for every integrator.
  if (volume_ && volume_->mode == VolumeMode::penalty)
    add_volume_penalty_forces(x, volume_->triangles, {}, volume_->at(time_), volume_->penalty_stiffness, f);
}

StepReport PromayonBody::step(State& state, const std::vector<std::uint8_t>& fixed, const Vector& external,
                              const std::vector<NodalSpring>& springs, const ImplicitEulerSettings& settings,
                              double start_time) {
  const VolumeControl* volume = volume_ ? &*volume_ : nullptr;
  StepReport out;
  if (!stepping_.implicit) out.cg.converged = true;
  State next = state;
  SeedStepReport last;
  double worst = worst_volume_error_;
  const auto track_volume = [&](const SeedStepReport& r, double& w) {
    if (volume && volume->mode == VolumeMode::exact && r.volume_target > 0)
      w = std::max(w, std::abs(r.volume - r.volume_target) / r.volume_target);
  };
  if (stepping_.implicit) {
    const Vector before = next.positions;
    out = implicit_euler_step(*this, next, fixed, external, springs, settings, nullptr, nullptr);
    if (out.nonfinite || !apply_seed_constraints(next, before, fixed, settings.dt, volume, start_time + settings.dt, last)) {
      out.nonfinite = true;
      return out;
    }
  } else {
    SeedStepSettings seed{settings.dt / stepping_.substeps, stepping_.damping, stepping_.mass_damping, stepping_.scheme};
    for (int k = 1; k <= stepping_.substeps; ++k) {
      // The penalty is added by the seed step itself: pass the forces alone.
      last = seed_explicit_step(*forces_, next, fixed, external, springs, seed, volume, start_time + k * seed.dt);
      if (last.nonfinite) {
        out.nonfinite = true;
        return out;
      }
      if (k < stepping_.substeps) track_volume(last, worst);
    }
  }
  state = std::move(next);
  time_ = start_time + settings.dt;
  last_ = last;
  track_volume(last, worst);
  worst_volume_error_ = worst;
  out.elastic_energy = forces_->elastic_energy(state.positions);
  const Vector& m = lumped_masses();
  out.kinetic_energy = 0;
  for (Eigen::Index i = 0; i < state.velocities.size(); ++i) out.kinetic_energy += 0.5 * m[i / 3] * state.velocities[i] * state.velocities[i];
  return out;
}

}  // namespace incise::physics
