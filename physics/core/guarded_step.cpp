#include "physics/core/guarded_step.hpp"

#include <algorithm>
#include <utility>

namespace incise::physics {

namespace {

// The energy watchdog and the tool force, after a step that stayed finite.
void watch_energy(BodyData& body, const Vector& external, const std::vector<NodalSpring>& springs,
                  const Vector& positions_before, const StepReport& step, GuardedStepReport& report) {
  report.elastic_energy = step.elastic_energy;
  report.kinetic_energy = step.kinetic_energy;
  double work = external.dot(body.state.positions - positions_before);
  for (const auto& spring : springs) {
    const Vec3 moved = body.state.positions.segment<3>(3 * spring.node) - positions_before.segment<3>(3 * spring.node);
    work += spring.force.dot(moved);
    const Vec3 applied = spring.force - spring.stiffness * moved;
    for (int i = 0; i < 3; ++i) report.tool_force[i] -= applied[i];
  }
  const double energy = step.elastic_energy + step.kinetic_energy;
  const double excess = energy - body.last_energy - std::max(work, 0.0);
  if (excess > 0.5 * body.last_energy + 1e-9) {
    report.energy_growth++;
    report.events.push_back({"energy_growth", "energy " + std::to_string(body.last_energy) + " -> " +
                                                  std::to_string(energy) + " J with " + std::to_string(work) +
                                                  " J of external work"});
  }
  body.last_energy = energy;
}

}  // namespace

GuardedStepReport guarded_step(const BodyModel& model, BodyData& body, const Vector& external,
                               const std::vector<NodalSpring>& springs, int max_retries, const StepFunction& step) {
  GuardedStepReport report;
  const Vector positions_before = body.state.positions;
  for (int attempt = 0; attempt <= max_retries; ++attempt) {
    const int substeps = 1 << attempt;
    ImplicitEulerSettings settings = model.integrator;
    settings.dt = model.integrator.dt / substeps;
    State saved = body.state;
    WarmStart saved_warm_start = body.warm_start;
    bool failed = false;
    StepReport last;
    for (int s = 0; s < substeps && !failed; ++s) {
      last = step(body.state, settings, &body.warm_start);
      report.cg_iterations += last.cg.iterations;
      report.cg_residual = std::max(report.cg_residual, last.cg.relative_residual);
      if (last.cg.stopped_by_budget && !last.nonfinite) {
        // Real time: the step's time was up (cg.hpp, CgBudget); counted, not a guard.
        report.cg_converged = false;
        report.cg_budget_stops++;
      } else if (!last.cg.converged && !last.nonfinite) {
        report.cg_converged = false;
        report.cg_not_converged++;
        report.events.push_back({"cg_not_converged", "relative residual " + std::to_string(last.cg.relative_residual) +
                                                         " after " + std::to_string(last.cg.iterations) +
                                                         " iterations (tolerance " + std::to_string(settings.cg.tolerance) + ")"});
      }
      failed = last.nonfinite;
    }
    if (!failed) {
      watch_energy(body, external, springs, positions_before, last, report);
      if (attempt > 0)
        report.events.push_back({"nonfinite_retry", "recovered with " + std::to_string(substeps) + " sub-steps of " +
                                                        std::to_string(settings.dt) + " s"});
      return report;
    }
    body.state = std::move(saved);
    body.warm_start = std::move(saved_warm_start);
    report.nonfinite_retries++;
  }
  report.ok = false;
  report.events.push_back({"nonfinite_retry", "gave up after " + std::to_string(max_retries) + " halvings"});
  return report;
}

}  // namespace incise::physics
