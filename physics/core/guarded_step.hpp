// The solve stage of a body with its guards, always on: a step that produces a non-finite
// value leaves the state untouched and is retried as 2, 4, ... sub-steps (dt halved each time)
// before giving up; CG non-convergence is reported with its residual; an energy watchdog flags
// growth beyond the work of the external and contact forces (implicit Euler dissipates, so a
// clear excess is the signature of an instability or of a step far outside the linearisation).
// Every guard that fires is returned as an event, in the order it fired, for the caller to
// count and log.
#pragma once

#include "physics/core/body.hpp"
#include "physics/core/implicit_euler.hpp"

#include <array>
#include <functional>
#include <string>
#include <vector>

namespace incise::physics {

struct GuardFired {
  std::string kind;    // "nonfinite_retry", "cg_not_converged", "energy_growth"
  std::string detail;  // figures: residual, energies, dt
};

struct GuardedStepReport {
  bool ok = true;        // false: still non-finite after every retry (the state is as before)
  int cg_iterations = 0;  // summed over the sub-steps
  double cg_residual = 0;  // the worst relative residual
  bool cg_converged = true;
  int nonfinite_retries = 0;
  int cg_not_converged = 0;
  int cg_budget_stops = 0;  // solves stopped unconverged by their real-time budget (cg.hpp)
  int energy_growth = 0;
  double elastic_energy = 0, kinetic_energy = 0;  // of the new state
  // The force of the tissue on the tool: minus the contact forces the implicit step applied,
  // the linearised ones at the end of the step, f - K dx (not the larger penetration force at
  // its start).
  std::array<double, 3> tool_force{};
  std::vector<GuardFired> events;
};

// One implicit Euler step of the body (sub-steps of it on a retry) by `step`, which advances
// the state with the given settings and CG's start (the CPU's implicit_euler_step or the GPU's).
using StepFunction = std::function<StepReport(State& state, const ImplicitEulerSettings& settings, WarmStart* warm_start)>;

GuardedStepReport guarded_step(const BodyModel& model, BodyData& body, const Vector& external,
                               const std::vector<NodalSpring>& springs, int max_retries, const StepFunction& step);

}  // namespace incise::physics
