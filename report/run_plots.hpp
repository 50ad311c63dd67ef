// The plots of one run, drawn by gnuplot from steps.csv: tool force, step time per phase,
// CG iterations, energy, cut events and (when steps.csv has tool_x, tool_y) the tool's path
// seen from above. Steps that cut (steps.csv cut_event, or links_severed) are shaded on every
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

// Writes one gnuplot script per plot (data inline) into out_dir and draws each PNG there.
RunPlots draw_run_plots(const CsvTable& steps, const std::filesystem::path& out_dir, std::ostream& progress);

bool gnuplot_installed();

}  // namespace incise::report
