// solve: the external forces (gravity, the scene's loads at the step's end) and one guarded
// implicit Euler step per body on its backend, or the model's own step (BodyModel::own_step)
// (physics/core/guarded_step.hpp), whose guards are counted and logged here.
#include "engine/world.hpp"

#include "physics/core/guarded_step.hpp"
#include "physics/cut/rest_cut.hpp"
#include "physics/gpu/efg_step.hpp"

#include <algorithm>
#include <functional>
#include <memory>
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

// The factor this step's CG is preconditioned with (nullptr: Jacobi); the first is built here,
// those after a cut beside the steps (physics/solve/rest_preconditioner.hpp).
const physics::RestFactor* World::prepare_preconditioner(Body& body, StepStats& stats) {
  const physics::ImplicitEulerSettings& integrator = body.model->integrator;
  const double dt = integrator.dt;
  physics::PreconditionerReport report;
  physics::Executor& executor = body.threads();
  // A build's coarse space splits where the cut hides a node from a vertex: it takes a copy of
  // the rest cut as it stands (the cut goes on meanwhile).
  std::function<physics::CutSeparation()> separation;
  if (body.cut && body.cut->rest_cut && body.cut->rest_cut->size() > 0)
    separation = [&body]() -> physics::CutSeparation {
      auto cut = std::make_shared<const physics::RestCut>(*body.cut->rest_cut);
      return {[cut](const physics::Vec3& lo, const physics::Vec3& hi) { return cut->near_box(lo, hi, 0); },
              [cut](const physics::Vec3& a, const physics::Vec3& b) { return cut->crosses(a, b); }};
    };
  const physics::RestFactor* factor = body.data.preconditioner.prepare(
      body.model->preconditioner, *body.data.mechanics, body.data.fixed, 1.0 + dt * integrator.rayleigh_mass,
      dt * integrator.rayleigh_stiffness + dt * dt, body.data.topology_revision, static_cast<long long>(steps_), executor,
      report, separation);
  if (!report.build_error.empty())
    log_guard(body.model->name, "preconditioner_build_failed",
              "a factor's build failed (" + report.build_error + "); the steps go on with the previous one");
  if (factor) {
    stats.preconditioner = physics::to_string(body.model->preconditioner.kind);
    stats.preconditioner_age = std::max(stats.preconditioner_age, report.age);
    stats.preconditioner_build_ms = std::max(stats.preconditioner_build_ms, report.build_ms);
    stats.preconditioner_wait_ms += report.wait_ms;
  }
  return factor;
}

void World::solve(Body& body, const std::vector<physics::NodalSpring>& springs,
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
  if (body.cut) body.cut->previous_positions = body.data.state.positions;
  const physics::RestFactor* factor = body.gpu ? nullptr : prepare_preconditioner(body, stats);
  // A model that steps itself (BodyModel::own_step) gets each step's start time: an attempt of
  // the guarded step is a run of equal dt's from the step's start, a retry a new run of half that.
  double attempt_dt = 0, clock = 0;
  const physics::StepFunction step = [&](physics::State& state, const physics::ImplicitEulerSettings& given,
                                         physics::WarmStart* warm_start) {
    physics::ImplicitEulerSettings settings = given;
    settings.cg.budget = budget_.next();
    if (given.dt != attempt_dt) {
      attempt_dt = given.dt;
      clock = end_time - body.model->integrator.dt;
    }
    // The GPU starts from the newest dv alone and gives back its own.
    const auto gpu_step = [&] {
      physics::Vector dv = warm_start->newest(state.positions.size());
      const physics::StepReport gpu = body.gpu->step(*body.data.efg, state, body.data.fixed, external, springs, settings, &dv);
      if (!gpu.nonfinite) warm_start->record(dv);
      return gpu;
    };
    const physics::StepReport report =
        body.gpu               ? gpu_step()
        : body.model->own_step ? body.model->own_step(*body.data.mechanics, state, body.data.fixed, external, springs, settings, clock)
                               : physics::implicit_euler_step(*body.data.mechanics, state, body.data.fixed, external, springs,
                                                              settings, warm_start, factor);
    budget_.solved(report.cg);
    stats.ms_assembly += report.assembly_ms;
    if (!report.nonfinite) clock += given.dt;
    return report;
  };
  const physics::GuardedStepReport report =
      physics::guarded_step(*body.model, body.data, external, springs, scene_.solver.max_retries, step);
  stats.cg_iterations += report.cg_iterations;
  stats.cg_residual = std::max(stats.cg_residual, report.cg_residual);
  stats.cg_converged = stats.cg_converged && report.cg_converged;
  stats.cg_budget_stops += report.cg_budget_stops;
  stats.nonfinite_events += report.nonfinite_retries;
  stats.energy_growth_events += report.energy_growth;
  stats.elastic_energy += report.elastic_energy;
  stats.kinetic_energy += report.kinetic_energy;
  for (int i = 0; i < 3; ++i) stats.tool_force[i] += report.tool_force[i];
  guard_counts_.cg_not_converged += report.cg_not_converged;
  guard_counts_.energy_growth += report.energy_growth;
  guard_counts_.nonfinite_retries += report.nonfinite_retries;
  for (const auto& event : report.events) log_guard(body.model->name, event.kind, event.detail);
  if (!report.ok)
    throw NonFiniteError("step " + std::to_string(steps_ + 1) + " (t = " + std::to_string(end_time) +
                         " s), body '" + body.model->name + "': non-finite values after " +
                         std::to_string(scene_.solver.max_retries) + " retries with halved dt");
}

}  // namespace incise::engine
