// The benchmarks' figures: each writes a gnuplot script with its data inline beside its CSV,
// and draws the PNG with gnuplot where it is installed (the CSV and the script are the report;
// the PNG is a convenience, so a missing gnuplot is said, not an error).
#pragma once

#include <filesystem>
#include <ostream>
#include <string>

namespace incise::bench {

// Writes `script` to out_dir/script_name (throws std::runtime_error if it cannot) and runs
// gnuplot on it in out_dir, where the script's `set output` names png_name. Says on `progress`
// when gnuplot is not installed or fails.
void draw_with_gnuplot(const std::filesystem::path& out_dir, const std::string& script_name, const std::string& script,
                       const std::string& png_name, std::ostream& progress);

}  // namespace incise::bench
