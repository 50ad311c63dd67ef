// The cutting performance report (issue 4): `incise bench performance [--quick] --out DIR`.
#pragma once

#include <filesystem>
#include <ostream>

namespace incise::bench {

// Replays the incision of the default scene (a blade pressed into the liver-like lobe and
// drawn along it) at several resolutions of the integration grid and of the cut surface, and
// writes DIR/performance.csv: scene,backend,elements,triangles,ms_ccd,ms_topology,ms_solve,
// ms_surface,ms_total (medians over the steps the blade was engaged near the body), then
// dofs,steps,ms_topology_max,cut_share_pct,cut_events. Progress and a table go to `progress`.
// Returns 0 on success, 1 on failure (with a message on `progress`).
int run_performance_bench(bool quick, const std::filesystem::path& out_dir, std::ostream& progress);

}  // namespace incise::bench
