// The error-against-run-time report of the deformable models (issue 3): `incise bench
// accuracy [--quick] --out DIR`.
#pragma once

#include <filesystem>
#include <ostream>

namespace incise::bench {

// Writes DIR/accuracy.csv, DIR/references.json, DIR/accuracy.gnuplot and (with gnuplot)
// DIR/accuracy.png. Progress and the reference refinement checks go to `progress`.
// Returns 0 on success, 1 on failure (with a message on `progress`).
int run_accuracy_bench(bool quick, const std::filesystem::path& out_dir, std::ostream& progress);

}  // namespace incise::bench
