#include "engine/models/constraint_particles_settings.hpp"

namespace incise::engine {

void read_constraint_particles_settings(Reader& block, BodySpec& body) {
  ConstraintParticlesSettings s;
  s.distance_stiffness = block.number("distance_stiffness", false, s.distance_stiffness, 0, 1e9);
  s.area_stiffness = block.number("area_stiffness", false, s.area_stiffness, 0, 1e9);
  s.volume_stiffness = block.number("volume_stiffness", false, s.volume_stiffness, 0, 1e9);
  if (s.distance_stiffness == 0 && s.area_stiffness == 0 && s.volume_stiffness == 0)
    block.error(block.child("distance_stiffness"), "at least one of distance_stiffness, area_stiffness and volume_stiffness must be > 0");
  s.stiffness_per = block.text("stiffness_per", false, s.stiffness_per, {"constraint", "volume"});
  s.area_on = block.text("area_on", false, s.area_on, {"surface", "every_face"});
  s.damping = block.text("damping", false, s.damping, {"relative", "constraint"});
  s.damping_coefficient = block.number("damping_coefficient", false, 0, 0, 1e9);
  s.integrator = block.text("integrator", false, s.integrator,
                            {"velocity_verlet", "explicit_euler", "rk2", "rk4", "verlet", "implicit_euler"});
  s.stretch_stiffness = block.number("stretch_stiffness", false, s.stretch_stiffness, 0, 1);
  s.stretch_alpha = block.number("stretch_alpha", false, s.stretch_alpha, 1, 10);
  s.stretch_iterations = block.integer("stretch_iterations", false, 1, 1, 1000);
  if (block.has("floor_z")) {
    s.floor_z = block.number("floor_z", false, 0, -1e6, 1e6);
    if (s.integrator == "implicit_euler")
      block.error(block.child("floor_z"), "the floor acts in the explicit integrators' step only, not with 'implicit_euler'");
  }
  if (s.integrator == "implicit_euler" && block.has("stretch_stiffness") && s.stretch_stiffness > 0)
    block.error(block.child("stretch_stiffness"), "the stretch limiter follows the explicit integrators' step only, not 'implicit_euler'");
  if (const Json* r = block.get("relax", false)) {
    Reader relax(*r, block.child("relax"), block.errors());
    s.relax.tolerance = relax.number("tolerance", false, s.relax.tolerance, 0, 1e9, true);
    s.relax.max_steps = relax.integer("max_steps", false, s.relax.max_steps, 1, 10000000);
    s.relax.calm_steps = relax.integer("calm_steps", false, s.relax.calm_steps, 1, 1000000);
    s.relax.mass_damping = relax.number("mass_damping", false, s.relax.mass_damping, 0, 1e4);
  }
  body.settings = s;
}

}  // namespace incise::engine
