// The cutting performance report: `incise bench performance [--quick] --out DIR`.
#pragma once

#include <filesystem>
#include <ostream>
#include <string>

namespace incise::bench {

// Replays the incision of the default scene (a blade pressed into the liver-like lobe and
// drawn along it) at several resolutions of the integration grid and of the cut surface, and
// writes DIR/performance.csv: scene,backend,elements,triangles,ms_ccd,ms_topology,ms_solve,
// ms_surface,ms_total (medians over the steps the blade was engaged near the body), then
// dofs,steps,ms_topology_max,cut_share_pct,cut_events,device,bytes_uploaded_per_cut_step,
// bytes_full_upload (the last three: "cpu", 0, 0 on the cpu). Progress and a table go to `progress`.
// Returns 0 on success, 1 on failure (with a message on `progress`).
// backend "gpu": each size also runs on the GPU backend (rows with backend=gpu, the device
// and the bytes uploaded per cut step). The cut_surface column is "front", the one design.
// `multigrid`: the scene's multigrid_smoothing and multigrid_precision for every row
// (0 and "": the scene's own); the csv's last two columns name the ones used.
struct MultigridOverrides {
  int smoothing = 0;
  std::string precision;
};
int run_performance_bench(bool quick, const std::filesystem::path& out_dir, std::ostream& progress,
                          const std::string& backend = "cpu", const std::string& preconditioner = "all",
                          const MultigridOverrides& multigrid = {});

}  // namespace incise::bench
