// The numerical stability sweep (issue 7): `incise bench stability [--quick] --out DIR`.
#pragma once

#include <filesystem>
#include <ostream>

namespace incise::bench {

// Runs every model x integrator x case x E x nu x dt of the sweep (a representative subset
// with `quick`) and writes
//   DIR/stability.csv          model,integrator,case,E,nu,dt,outcome,max_energy_ratio,
//                              max_displacement,steps,guard_events (one row per run);
//   DIR/stability_summary.txt  the outcome bounds, the cases' set-up and the outcome counts;
//   DIR/stability.gnuplot and, with gnuplot installed, DIR/stability.png (the outcome map).
// A carriage-return progress line, then the outcome counts per model and integrator, go to
// `progress`. Returns 0 on success, 1 on failure (with a message on `progress`).
// resume: keep the runs already in out_dir/stability.csv (an interrupted sweep, or the parts of
// a batch merged into one file) and run only the missing ones; the summary and the plot cover
// them all. part/parts: run only the runs whose index in the sweep is part modulo parts (a
// batch job, docs/batch.md), without the thin-slice study, which the merge runs once.
struct StabilityOptions {
  bool quick = false;
  bool resume = false;
  int part = 0;
  int parts = 1;
};
int run_stability_bench(const StabilityOptions& options, const std::filesystem::path& out_dir, std::ostream& progress);

}  // namespace incise::bench
