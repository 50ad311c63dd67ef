// The plots of one run, drawn by gnuplot from steps.csv: tool force, step time per phase,
// CG iterations, energy, cut events, and the organ at rest from above (rest_top.csv) under
// the tool's path (when steps.csv has tool_x, tool_y). Steps that cut (steps.csv cut_event, or links_severed) are shaded on every
// time axis.
#pragma once

#include "report/csv_table.hpp"

#include <filesystem>
#include <ostream>
#include <string>
#include <vector>

namespace incise::report {

struct Plot {
  std::filesystem::path png;  // may be missing when gnuplot is not installed or failed
  std::string title;
  std::string id;  // the <img> id on the page
};

struct RunPlots {
  std::vector<Plot> plots;
  std::vector<std::string> notes;  // a plot skipped and why (a column missing)
};

// What the view from above draws besides the tool's path, each null when the run has none:
// rest_top.csv (x,y of the surface at rest), plan.csv (x,y,z of the planned incision) and
// cut_path.csv (x0,y0,z0,x1,y1,z1: the wound's mouth at rest), from engine/incision_score.hpp.
struct TopView {
  const CsvTable* rest_top = nullptr;
  const CsvTable* plan = nullptr;
  const CsvTable* cut_path = nullptr;
};

// Writes one gnuplot script per plot (data inline) into out_dir and draws each PNG there.
RunPlots draw_run_plots(const CsvTable& steps, const TopView& top, const std::filesystem::path& out_dir,
                        std::ostream& progress);

bool gnuplot_installed();

}  // namespace incise::report
