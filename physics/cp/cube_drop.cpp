#include "physics/cp/cube_drop.hpp"

#include "physics/core/implicit_euler.hpp"

namespace incise::physics {

CubeDropResult run_cube_drop(const CubeDrop& drop) {
  const Vec3 lo(0, 0, drop.drop);
  const TetMesh mesh = make_box_tets5(lo, lo + Vec3::Constant(drop.side), {drop.cells, drop.cells, drop.cells});
  ConstraintParticleSettings settings;
  settings.density = drop.density;
  settings.distance_stiffness = drop.stiffness;
  settings.area_stiffness = drop.area ? drop.stiffness : 0;
  settings.volume_stiffness = drop.volume ? drop.stiffness : 0;
  settings.area_on_every_face = true;  // the thesis's cube: 5,504 area constraints
  settings.damping_coefficient = drop.damping;
  ConstraintParticles model(mesh, settings);
  CpStepSettings step;
  step.dt = drop.dt;
  step.limiter.enabled = drop.limiter;
  step.floor_z = 0.0;
  State state{mesh.rest, Vector::Zero(mesh.rest.size())};
  const Vector gravity = gravity_forces(model.lumped_masses(), Vec3(0, 0, -drop.gravity));
  const double rest_volume = model.volume(mesh.rest);
  CubeDropResult result;
  result.volume_ratio.push_back(1);
  result.inverted.push_back(0);
  for (int frame = 1; frame <= drop.frames && result.finite; ++frame) {
    CpStepReport report;
    for (int k = 0; k < drop.steps_per_frame; ++k) {
      report = constraint_particles_step(model, state, {}, gravity, step, model.verlet_history());
      if (report.nonfinite) {
        result.finite = false;
        break;
      }
    }
    result.volume_ratio.push_back(model.volume(state.positions) / rest_volume);
    result.inverted.push_back(report.inverted_tets);
  }
  return result;
}

}  // namespace incise::physics
