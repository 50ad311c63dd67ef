// `incise bench needle --out DIR` (issue 30): the needle of assets/scenes/needle_cube.json (the
// seed's cube of 125 particles, seed 002 §8.9) inserted and withdrawn at three speeds, each run
// the scene's trajectory with its times scaled. DIR/needle.csv has one row per step
// (run,time_s,depth_m,force_axial_N,force_lateral_N,phase; the axial force is the tissue's
// resistance, positive against the needle's motion into the tissue), DIR/needle.png the force
// against depth. Prints each run's puncture peak, the resistance early and late in the
// insertion, the retraction's largest force and the stick / slip transitions.
#pragma once

#include <filesystem>
#include <ostream>

namespace incise::bench {

struct NeedleBenchOptions {
  std::filesystem::path scene;  // empty: assets/scenes/needle_cube.json
  std::filesystem::path out_dir = "out/bench/needle";
};

// Returns 0, or 1 with the reason on `progress` when a run fails or the seed's qualitative
// results do not hold (a puncture peak above the resistance past it, growth with depth, no
// cutting force on retraction).
int run_needle_bench(const NeedleBenchOptions& options, std::ostream& progress);

}  // namespace incise::bench
