// solve: one implicit Euler step per body (CPU or GPU), with its guards: the non-finite retry
// with halved dt, CG non-convergence and the energy watchdog, each counted and logged.
#include "engine/world.hpp"

#include "physics/core/contact.hpp"
#include "physics/gpu/efg_step.hpp"

#include <algorithm>
#include <string>

namespace incise::engine {

std::array<double, 3> load_force_at(const LoadSpec& load, double time) {
  const auto& e = load.events;
  if (time <= e.front().time) return e.front().force;
  if (time >= e.back().time) return e.back().force;
  auto it = std::upper_bound(e.begin(), e.end(), time,
                             [](double t, const LoadEvent& ev) { return t < ev.time; });
  const LoadEvent& b = *it;
  const LoadEvent& a = *(it - 1);
  double s = (time - a.time) / (b.time - a.time);
  return {a.force[0] + s * (b.force[0] - a.force[0]), a.force[1] + s * (b.force[1] - a.force[1]),
          a.force[2] + s * (b.force[2] - a.force[2])};
}

void World::solve_body(Body& body, const std::vector<physics::NodalSpring>& springs,
                       double end_time, StepStats& stats) {
  physics::Vector external = body.data.gravity;
  for (std::size_t k = 0; k < body.model->load_nodes.size(); ++k) {
    auto force = load_force_at(scene_.loads[body.model->load_index[k]], end_time);
    double total_mass = 0;
    for (int i : body.model->load_nodes[k]) total_mass += body.data.mechanics->lumped_masses()[i];
    for (int i : body.model->load_nodes[k]) {
      double share = body.data.mechanics->lumped_masses()[i] / total_mass;
      for (int c = 0; c < 3; ++c) external[3 * i + c] += share * force[c];
    }
  }
  const physics::Vector positions_before = body.data.state.positions;
  if (body.cut) body.cut->previous_positions = body.data.state.positions;
  // Non-finite guard: a step that produces a non-finite value leaves the state untouched
  // and is retried as 2, 4, ... sub-steps (dt halved each time) before giving up.
  for (int attempt = 0; attempt <= scene_.solver.max_retries; ++attempt) {
    int substeps = 1 << attempt;
    physics::ImplicitEulerSettings settings = body.model->integrator;
    settings.dt = body.model->integrator.dt / substeps;
    physics::State saved = body.data.state;
    physics::Vector saved_velocity_change = body.data.velocity_change;
    bool failed = false;
    physics::StepReport report;
    for (int s = 0; s < substeps && !failed; ++s) {
      report = body.gpu ? body.gpu->step(*body.data.efg, body.data.state, body.data.fixed, external, springs, settings,
                                         &body.data.velocity_change)
                        : physics::implicit_euler_step(*body.data.mechanics, body.data.state, body.data.fixed, external, springs,
                                                       settings, &body.data.velocity_change);
      stats.cg_iterations += report.cg.iterations;
      stats.cg_residual = std::max(stats.cg_residual, report.cg.relative_residual);
      if (!report.cg.converged && !report.nonfinite) {
        stats.cg_converged = false;
        guard_counts_.cg_not_converged++;
        log_guard(body.model->name, "cg_not_converged",
                  "relative residual " + std::to_string(report.cg.relative_residual) + " after " +
                      std::to_string(report.cg.iterations) + " iterations (tolerance " +
                      std::to_string(settings.cg.tolerance) + ")");
      }
      failed = report.nonfinite;
    }
    if (!failed) {
      stats.elastic_energy += report.elastic_energy;
      stats.kinetic_energy += report.kinetic_energy;
      // Energy watchdog: implicit Euler dissipates, so the energy may grow only by the work
      // of the external and contact forces over the step. A clear excess is the signature
      // of an instability (or of a step far outside the linearisation) and is reported.
      double work = external.dot(body.data.state.positions - positions_before);
      for (const auto& spring : springs) {
        const physics::Vec3 moved = body.data.state.positions.segment<3>(3 * spring.node) -
                                    positions_before.segment<3>(3 * spring.node);
        work += spring.force.dot(moved);
        // The contact force the implicit step applied is the linearised one at the end of
        // the step, f - K dx: that is what the tissue pushes the tool with, not the larger
        // penetration force at the start of the step.
        const physics::Vec3 applied = spring.force - spring.stiffness * moved;
        for (int i = 0; i < 3; ++i) stats.tool_force[i] -= applied[i];
      }
      const double energy = report.elastic_energy + report.kinetic_energy;
      const double excess = energy - body.data.last_energy - std::max(work, 0.0);
      if (excess > 0.5 * body.data.last_energy + 1e-9) {
        stats.energy_growth_events++;
        guard_counts_.energy_growth++;
        log_guard(body.model->name, "energy_growth",
                  "energy " + std::to_string(body.data.last_energy) + " -> " + std::to_string(energy) +
                      " J with " + std::to_string(work) + " J of external work");
      }
      body.data.last_energy = energy;
      if (attempt > 0)
        log_guard(body.model->name, "nonfinite_retry",
                  "recovered with " + std::to_string(substeps) + " sub-steps of " +
                      std::to_string(settings.dt) + " s");
      return;
    }
    body.data.state = std::move(saved);
    body.data.velocity_change = std::move(saved_velocity_change);
    stats.nonfinite_events++;
    guard_counts_.nonfinite_retries++;
  }
  log_guard(body.model->name, "nonfinite_retry", "gave up after " + std::to_string(scene_.solver.max_retries) + " halvings");
  throw NonFiniteError("step " + std::to_string(steps_ + 1) + " (t = " + std::to_string(end_time) +
                       " s), body '" + body.model->name + "': non-finite values after " +
                       std::to_string(scene_.solver.max_retries) + " retries with halved dt");
}

}  // namespace incise::engine
