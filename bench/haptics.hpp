// The haptics benchmark (issue 5): `incise bench haptics --seconds S --out DIR`.
#pragma once

#include <filesystem>
#include <ostream>
#include <string>

namespace incise::bench {

struct HapticsBenchOptions {
  double seconds = 10;         // per run: cutting, without cutting, bare loop
  std::filesystem::path scene;  // empty: assets/scenes/haptics_block.json
  std::filesystem::path out_dir = "out/bench/haptics";
  double spin_us = 300;         // sleep to this long before each deadline, then spin
  bool realtime_priority = true;
  // Pin the loop's thread and the bare loop beside it (and the bare loop alone) to one CPU, so
  // that a stall of that CPU shows in both and long_periods_not_in counts the loop's own:
  // `cpu`, or with -1 the last CPU the process may run on. Physics is left free. Where the
  // process may not set affinity the loops run unpinned and haptics.json's `cpu` says null.
  bool pin = true;
  int cpu = -1;
  // The cutting run's ticks (poses, buttons, forces) and CG stops to this trajectory file, so
  // a run that fails can be replayed headless, bit for bit (`incise replay SCENE --trajectory
  // FILE`): real time makes each run's states differ. Empty: not recorded.
  std::filesystem::path record;
};

// Three runs of `seconds` each, in this process: (1) the 1 kHz loop on its own thread with a
// scripted virtual device drawing a blade through the scene (engaged: it cuts) while physics
// steps on its own thread, (2) the same strokes with the blade never engaged (no cut), (3) a
// bare timing loop (nothing but the wait). Writes DIR/haptics.json: rate_hz, period_us {p50,
// p99, p999, max}, missed_2ms, force_jump_at_cut_N_per_ms {max} and the rest for (1) at the
// top level, the same under `without_cutting` for (2), `baseline` for (3). Prints a summary.
// Returns 0, or 1 with a message on `progress`.
int run_haptics_bench(const HapticsBenchOptions& options, std::ostream& progress);

}  // namespace incise::bench
