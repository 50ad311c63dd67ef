// Synthetic tool trajectories for assets and tests: scripted motions that need no haptic
// device, recorded in the same form as a real session so they replay through the same path.
#pragma once

#include <array>
#include <vector>

#include "engine/trajectory.hpp"

namespace incise::engine {

// A probe poke: approach from above, press into the tissue, hold, slide sideways while still
// pressed, lift back out to the approach height. Every phase is eased with a smoothstep, so the
// velocity is continuous (zero at each phase boundary) and the path is C1.
struct PokeSpec {
  std::array<double, 3> approach_point{0, 0, 0.05};  // start of the path, above the body (z up)
  std::array<double, 3> contact_point{0, 0, 0};      // on the surface, where the tip first touches
  // How far past the contact point the tip is pressed, along the approach direction (from the
  // approach point towards the contact point).
  double depth = 0.005;
  // The slide while pressed; any part along the approach direction is dropped so the depth
  // stays constant during it.
  std::array<double, 3> stroke{0.02, 0, 0};
  std::array<double, 4> orientation{1, 0, 0, 0};  // held for the whole path; normalised
  double rate_hz = 1000;
  double approach_seconds = 0.5;
  double press_seconds = 0.3;
  double hold_seconds = 0.2;
  double stroke_seconds = 1.0;
  double release_seconds = 0.5;
};

// Samples at k / rate_hz from 0 to the total duration (plus one at the exact end when the
// duration is not a whole number of periods). buttons bit 0 is set exactly while the tip is
// below the contact surface. Force is not recorded (zero). Deterministic: the same spec gives
// the same bits on every run. Throws std::invalid_argument for an unusable spec (non-finite
// values, negative durations or depth, a moving phase of zero duration, approach point equal to
// contact point, zero quaternion, rate not positive).
std::vector<ToolSample> synthesize_poke(const PokeSpec& spec);

}  // namespace incise::engine
