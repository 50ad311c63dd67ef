// The needle's run in figures (metrics.json `needle`, `incise bench needle`): the seed's
// qualitative results (seed 002 §2.3, §8.9) as numbers an expect block can bound.
#pragma once

#include "engine/world.hpp"

#include <cstddef>
#include <vector>

namespace incise::engine {

// Forces are the tissue's resistance to the needle (minus the axial force on it, N).
struct NeedleSummary {
  double puncture_peak = 0;       // the largest resistance while puncturing
  double insert_early_mean = 0;   // mean resistance advancing, over the first third of the depth past the puncture
  double insert_late_mean = 0;    // the same over the last third
  double retract_max = 0;         // the largest |axial force| while retracting (friction only)
  double retract_cutting_max = 0; // the largest cutting force while retracting (0: none)
  double lateral_max = 0;         // N
  double max_depth = 0;           // m
  double balance_max = 0;         // N, the worst |force on the needle + forces on the tissue|
  long stick_to_slip = 0, slip_to_stick = 0;
  int puncture_steps = 0, insert_steps = 0, retract_steps = 0;
  // The largest mean displacement of the bodies' nodes along the needle axis, m (seed 002 §5.8's
  // deformation along the needle axis; NeedleStepStats::axial_displacement).
  double axial_displacement_peak = 0;
};

// The needle's (a template's: its forces summed, StepStats::needle).
NeedleSummary summarise_needle(const std::vector<StepStats>& stats);
// The k-th needle of a template of several (StepStats::needles; no axial displacement).
NeedleSummary summarise_needle(const std::vector<StepStats>& stats, std::size_t k);

}  // namespace incise::engine
