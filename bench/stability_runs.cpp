// One run of the stability sweep: a body stepped by one integrator at one dt, with the
// engine's non-finite guard, judged by the outcomes bench/stability.cpp lists.
#include "bench/stability_sweep.hpp"

#include <algorithm>
#include <string>
#include <vector>

namespace incise::bench::sweep {

// ---- Runs --------------------------------------------------------------------------------

double max_node_displacement(const Vector& positions, const Vector& rest) {
  double largest = 0;
  for (Index node = 0; node < rest.size() / 3; ++node) {
    largest = std::max(largest, (positions.segment<3>(3 * node) - rest.segment<3>(3 * node)).norm());
  }
  return largest;
}

// The sweep's implicit Euler step (its damping and CG budget) at step `dt`: the runs and the
// thin-slice study step alike.
physics::ImplicitEulerSettings implicit_settings(double dt) {
  physics::ImplicitEulerSettings settings;
  settings.dt = dt;
  settings.rayleigh_mass = rayleigh_mass;
  settings.cg.tolerance = cg_tolerance;
  settings.cg.max_iterations = cg_max_iterations;
  return settings;
}

Run simulate(Body& body, const Integrator& integrator, double dt, double duration) {
  DeformableModel& model = *body.model;
  Run run;
  run.dt = dt;
  State state = body.initial;
  physics::VerletHistory history;
  physics::WarmStart warm_start;
  const Vector& rest = model.rest_positions();

  const double total_mass = model.lumped_masses().sum();
  const double initial_energy = model.elastic_energy(state.positions) +
                                physics::kinetic_energy(model.lumped_masses(), state.velocities);
  const double free_fall_work = 0.5 * total_mass * gravity.squaredNorm() * duration * duration;
  const double reference_energy = std::max(initial_energy, free_fall_work);
  run.max_displacement = max_node_displacement(state.positions, rest);
  run.max_energy_ratio = initial_energy / reference_energy;

  const int steps = std::max(1, static_cast<int>(std::lround(duration / dt)));
  // A model that knows its explicit bound (the mass-spring's, the constraint particles') refuses a step beyond it
  // (explicit_step throws): the run is counted as refused, not taken.
  if (!integrator.implicit && dt > model.explicit_step_limit()) {
    run.outcome = Outcome::refused;
    return run;
  }
  int capped_steps = 0;
  Vector before_last_solve = state.positions;
  physics::VolumeCutReport cuts;
  for (int step = 0; step < steps; ++step) {
    if (body.cutter && body.blade) {
      // As the engine does: the blade's sweep over this step against the particles' motion
      // over the previous one (positions before the last solve to after it), before the solve.
      const std::vector<Vec3> from = body.blade(step * dt), to = body.blade((step + 1) * dt);
      const physics::VolumeCutReport report =
          body.cutter->cut(from, to, before_last_solve, state.positions);
      if (report.any()) {
        pin_orphans(body, &state);
        body.external = physics::gravity_forces(model.lumped_masses(), gravity);
        cuts.elements_reselected += report.elements_reselected;
        cuts.elements_isolated += report.elements_isolated;
        cuts.reselection_failures += report.reselection_failures;
      }
    }
    before_last_solve = state.positions;
    bool accepted = false;
    bool capped = false;
    double energy = 0;
    for (int attempt = 0; attempt <= max_halvings && !accepted; ++attempt) {
      const int substeps = 1 << attempt;
      const double sub_dt = dt / substeps;
      const State saved_state = state;
      const physics::VerletHistory saved_history = history;
      const physics::WarmStart saved_start = warm_start;
      bool failed = false;
      capped = false;
      for (int sub = 0; sub < substeps && !failed; ++sub) {
        if (integrator.implicit) {
          const physics::StepReport report = physics::implicit_euler_step(
              model, state, body.fixed, body.external, {}, implicit_settings(sub_dt), &warm_start);
          failed = report.nonfinite;
          capped = capped || (!report.nonfinite && !report.cg.converged);
          energy = report.elastic_energy + report.kinetic_energy;
        } else {
          const physics::ExplicitSettings settings{sub_dt, rayleigh_mass};
          const physics::ExplicitStepReport report =
              body.own_explicit_step
                  ? body.own_explicit_step(integrator, state, body.fixed, body.external, settings, history)
                  : physics::explicit_step(integrator.scheme, model, state, body.fixed, body.external, settings,
                                           &history);
          failed = report.nonfinite;
          energy = report.elastic_energy + report.kinetic_energy;
        }
      }
      if (failed) {
        state = saved_state;
        history = saved_history;
        warm_start = saved_start;
        if (attempt == 0) ++run.guard_events;
        continue;
      }
      accepted = true;
    }
    if (!accepted) {
      run.outcome = Outcome::nonfinite;
      break;
    }
    run.steps = step + 1;
    capped_steps += capped ? 1 : 0;
    run.max_energy_ratio = std::max(run.max_energy_ratio, energy / reference_energy);
    run.max_displacement = std::max(run.max_displacement, max_node_displacement(state.positions, rest));
    if (run.max_energy_ratio > energy_bound || run.max_displacement > displacement_bound * body.size) {
      run.outcome = Outcome::diverged;
      break;
    }
    if (capped_steps > cg_capped_fraction * steps) break;  // cg_not_converged, below
  }
  if (run.outcome == Outcome::stable && capped_steps > cg_capped_fraction * steps) {
    run.outcome = Outcome::cg_not_converged;
  }
  if (body.count_inverted) run.inverted_at_end = body.count_inverted(state.positions);
  if (body.cutter && body.blade) body.note = count_pieces(*body.cutter, cuts);
  return run;
}


}  // namespace incise::bench::sweep
