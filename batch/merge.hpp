// `incise batch merge DIR`: the jobs' outcomes gathered into DIR/summary.csv (one row per
// job, in the manifest's order, whichever shard or rank ran it) and DIR/summary.png.
#pragma once

#include <filesystem>
#include <ostream>

namespace incise::batch {

struct MergeTotals {
  int jobs = 0, ok = 0, failed = 0, missing = 0;  // missing: no outcome.json (not run yet)
  bool benches_joined = true;  // every benchmark's parts joined into DIR/bench/NAME/ (batch/bench_job.hpp)
};

// Reads DIR/jobs.json and each DIR/jobs/NAME/outcome.json; throws std::runtime_error naming
// the file when one cannot be read.
MergeTotals merge_batch(const std::filesystem::path& out_dir, std::ostream& progress);

}  // namespace incise::batch
