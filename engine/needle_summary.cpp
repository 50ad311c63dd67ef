#include "engine/needle_summary.hpp"

#include <algorithm>
#include <cmath>

namespace incise::engine {

namespace {

NeedleSummary summarise(const std::vector<const NeedleStepStats*>& steps) {
  NeedleSummary s;
  double punctured_at = -1e300;  // the depth where the last puncture step ended
  for (const NeedleStepStats* step : steps) {
    const NeedleStepStats& n = *step;
    if (!n.present) continue;
    s.axial_displacement_peak = std::max(s.axial_displacement_peak, n.axial_displacement);
    s.max_depth = std::max(s.max_depth, n.depth);
    s.balance_max = std::max(s.balance_max, n.balance);
    s.lateral_max = std::max(s.lateral_max, n.lateral);
    s.stick_to_slip = n.stick_to_slip;
    s.slip_to_stick = n.slip_to_stick;
    if (n.phase == "puncture") {
      s.puncture_peak = std::max(s.puncture_peak, -n.axial);
      punctured_at = n.depth;
      ++s.puncture_steps;
    } else if (n.phase == "retract") {
      s.retract_max = std::max(s.retract_max, std::abs(n.axial));
      s.retract_cutting_max = std::max(s.retract_cutting_max, n.cutting);
      ++s.retract_steps;
    }
  }
  // Advancing past the puncture: the resistance over the first and the last third of that depth.
  double deepest = punctured_at;
  for (const NeedleStepStats* n : steps)
    if (n->phase == "insert" && n->speed > 0) deepest = std::max(deepest, n->depth);
  const double third = (deepest - punctured_at) / 3;
  double early = 0, late = 0;
  int n_early = 0, n_late = 0;
  for (const NeedleStepStats* step : steps) {
    const NeedleStepStats& n = *step;
    if (n.phase != "insert" || !(n.speed > 0) || n.depth < punctured_at) continue;
    ++s.insert_steps;
    if (n.depth <= punctured_at + third) early += -n.axial, ++n_early;
    if (n.depth >= deepest - third) late += -n.axial, ++n_late;
  }
  s.insert_early_mean = n_early ? early / n_early : 0;
  s.insert_late_mean = n_late ? late / n_late : 0;
  return s;
}

}  // namespace

NeedleSummary summarise_needle(const std::vector<StepStats>& stats) {
  std::vector<const NeedleStepStats*> steps;
  steps.reserve(stats.size());
  for (const auto& step : stats) steps.push_back(&step.needle);
  return summarise(steps);
}

NeedleSummary summarise_needle(const std::vector<StepStats>& stats, std::size_t k) {
  std::vector<const NeedleStepStats*> steps;
  steps.reserve(stats.size());
  for (const auto& step : stats)
    if (k < step.needles.size()) steps.push_back(&step.needles[k]);
  return summarise(steps);
}

}  // namespace incise::engine
