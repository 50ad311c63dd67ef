// Dionne's constraint particles (physics/cp/constraint_particles.hpp, seed 000): the nodes of the
// body's tetrahedra are particles held by distance, area and volume constraints, stepped by an
// explicit integrator (velocity Verlet by default) and the stretch limiter
// (physics/cp/cp_step.hpp) through BodyModel::own_step, or by the shared implicit Euler. A box
// generator is split into 5 tets per cube (the thesis's cube), any other shape filled as the fem
// model fills it (6 per cell, snapped). Its settings block is `constraint_particles`; it cannot
// be cut and runs on the CPU.
#include "engine/body_builder.hpp"
#include "engine/model_registry.hpp"
#include "engine/models/constraint_particles_settings.hpp"
#include "physics/core/stopwatch.hpp"
#include "physics/cp/cp_step.hpp"

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <string>
#include <vector>

namespace incise::engine {

namespace {

physics::TetMesh make_tets(const BodySpec& spec, const BodyShape& shape, physics::SnapReport* snap) {
  if (spec.generator && spec.generator->type == "box") {
    std::array<int, 3> cells{};
    for (int i = 0; i < 3; ++i)
      cells[i] = std::max(1, static_cast<int>(std::lround((shape.hi[i] - shape.lo[i]) / spec.resolution)));
    return physics::make_box_tets5(shape.lo, shape.hi, cells);
  }
  return fill_with_tets(spec, shape, spec.resolution, snap);
}

physics::ConstraintParticleSettings particle_settings(const ConstraintParticlesSettings& s, double density) {
  physics::ConstraintParticleSettings p;
  p.density = density;
  p.distance_stiffness = s.distance_stiffness;
  p.area_stiffness = s.area_stiffness;
  p.volume_stiffness = s.volume_stiffness;
  p.scaling = s.stiffness_per == "volume" ? physics::StiffnessScaling::per_volume : physics::StiffnessScaling::per_constraint;
  p.area_on_every_face = s.area_on == "every_face";
  p.damping = s.damping == "constraint" ? physics::ParticleDamping::constraint : physics::ParticleDamping::relative;
  p.damping_coefficient = s.damping_coefficient;
  return p;
}

// The explicit step's settings (the limiter, the floor) but dt and damping, which come from the
// solver; an implicit_euler body relaxes by velocity Verlet (settle_by_relaxation).
physics::CpStepSettings cp_step_settings(const ConstraintParticlesSettings& s) {
  physics::CpStepSettings step;
  if (s.integrator != "implicit_euler") step.scheme = *physics::explicit_scheme_from_name(s.integrator);
  step.limiter.enabled = s.stretch_stiffness > 0;
  step.limiter.stiffness = s.stretch_stiffness;
  step.limiter.alpha = s.stretch_alpha;
  step.limiter.iterations = s.stretch_iterations;
  step.floor_z = s.floor_z;
  return step;
}

// solver.start "settled": Alg. 3.2's relaxation (physics::relax) from rest under gravity with the
// body's own step at solver.dt (for an implicit_euler body, velocity Verlet at the smaller of
// solver.dt and 0.9 of the explicit bound) and its damping plus relax.mass_damping; returns the
// displacement settle_if_asked adds. A relaxation that blows up or does not settle within
// relax.max_steps is refused, with what it reached.
physics::Vector settle_by_relaxation(physics::ConstraintParticles& particles, const physics::BodyData& body,
                                     const physics::BodyModel& model, const ConstraintParticlesSettings& s) {
  physics::CpStepSettings step = cp_step_settings(s);
  step.dt = model.integrator.dt;
  if (s.integrator == "implicit_euler") step.dt = std::min(step.dt, 0.9 * particles.explicit_step_limit());
  step.rayleigh_mass = model.integrator.rayleigh_mass + s.relax.mass_damping;
  physics::State state{particles.rest_positions(), physics::Vector::Zero(particles.rest_positions().size())};
  const physics::RelaxReport report = physics::relax(particles, state, body.fixed, body.gravity, step,
                                                     {s.relax.tolerance, s.relax.max_steps, s.relax.calm_steps});
  particles.verlet_history() = {};  // the run starts afresh from the relaxed positions
  if (report.nonfinite)
    throw std::runtime_error("constraint_particles.relax: the relaxation produced a non-finite value after " +
                             std::to_string(report.steps) + " steps (a smaller solver.dt)");
  if (!report.converged)
    throw std::runtime_error("constraint_particles.relax: not settled after max_steps = " + std::to_string(report.steps) +
                             " steps (its energy still changes by tolerance or more per step; give it damping: "
                             "relax.mass_damping, damping_coefficient or damping.mass, or more max_steps)");
  return state.positions - particles.rest_positions();
}

// The explicit step with the limiter, as the engine's solve stage calls a model's own step.
physics::OwnStep explicit_step_of(const ConstraintParticlesSettings& s) {
  physics::CpStepSettings step = cp_step_settings(s);
  return [step](physics::DeformableModel& mechanics, physics::State& state, const std::vector<std::uint8_t>& fixed,
                const physics::Vector& external, const std::vector<physics::NodalSpring>& springs,
                const physics::ImplicitEulerSettings& given, double /*start_time*/) {
    auto& particles = dynamic_cast<physics::ConstraintParticles&>(mechanics);
    physics::CpStepSettings settings = step;
    settings.dt = given.dt;
    settings.rayleigh_mass = given.rayleigh_mass;
    physics::Vector forces = external;
    for (const physics::NodalSpring& spring : springs) forces.segment<3>(3 * spring.node) += spring.force;
    const physics::CpStepReport cp =
        physics::constraint_particles_step(particles, state, fixed, forces, settings, particles.verlet_history());
    physics::StepReport report;
    report.nonfinite = cp.nonfinite;
    report.cg.converged = true;  // no linear solve
    report.elastic_energy = cp.integrator.elastic_energy;
    report.kinetic_energy = physics::kinetic_energy(particles.lumped_masses(), state.velocities);
    return report;
  };
}

Body build_constraint_particles_body(const BodySpec& spec, const SolverSpec& solver, const BodyShape& shape) {
  Body result;
  auto model = body_model(spec, solver);
  model->rest_lo = shape.lo;
  model->rest_hi = shape.hi;
  physics::BodyData& body = result.data;
  const std::string where = "body '" + spec.name + "'";
  const auto settings = std::any_cast<ConstraintParticlesSettings>(spec.settings);
  physics::TetMesh mesh;
  try {
    physics::Stopwatch watch;
    mesh = make_tets(spec, shape, &model->snap);
    body.mechanics = std::make_unique<physics::ConstraintParticles>(mesh, particle_settings(settings, spec.material.density));
    result.build_ms.volume = watch.ms();
  } catch (const std::exception& e) {
    throw std::runtime_error(where + ": " + e.what());
  }
  model->elements = mesh.tets.size();
  if (settings.integrator != "implicit_euler") model->own_step = explicit_step_of(settings);
  body.surface = physics::boundary_triangles(mesh.tets);
  index_surface(*model, body, body.mechanics->node_count());
  start_at_rest(body);
  fix_nodes(body, spec, body.mechanics->rest_positions());
  body.gravity = physics::gravity_forces(body.mechanics->lumped_masses(), model->gravity);
  auto& particles = dynamic_cast<physics::ConstraintParticles&>(*body.mechanics);
  settle_if_asked(result, solver, where, [&] { return settle_by_relaxation(particles, body, *model, settings); });
  result.model = std::move(model);
  return result;
}

}  // namespace

void register_constraint_particles_model(ModelRegistry& registry) {
  registry.add({.name = "constraint_particles",
                .summary = "Dionne's particles held by distance, area and volume constraints, explicit + stretch limiter",
                .cuttable = false,
                .gpu = false,
                .node_name = "particle",
                .read_settings = read_constraint_particles_settings,
                .build = build_constraint_particles_body});
}

}  // namespace incise::engine
