// `incise bench performance`'s page: OUT/report.html from OUT/performance.csv, the phase
// medians of a cutting step stacked per row (gnuplot) and the table, for people to read.
#pragma once

#include <filesystem>
#include <ostream>

namespace incise::bench {

// Reads out_dir/performance.csv (throws std::runtime_error naming it when it cannot), draws
// out_dir/performance.png where gnuplot is installed and writes out_dir/report.html; returns its path.
std::filesystem::path write_performance_report(const std::filesystem::path& out_dir, std::ostream& progress);

}  // namespace incise::bench
