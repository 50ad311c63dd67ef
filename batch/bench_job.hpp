// A benchmark's sweep on the batch path (issue 36): `incise bench stability --emit-manifest
// FILE --parts N` writes a manifest of N jobs, each running every N-th run of the sweep into
// its own folder (a shard, a Slurm array task or an MPI rank takes it like any job), and
// `incise batch merge DIR` joins the parts' rows into DIR/bench/stability/, where the bench's
// own resume writes the CSV in the sweep's order, the summary, the plot and the page, as one
// unsharded run would (docs/batch.md).
#pragma once

#include "batch/manifest.hpp"

#include <nlohmann/json.hpp>

#include <filesystem>
#include <ostream>

namespace incise::batch {

// The manifest of a sweep in `parts` parts (jobs NAME_part_I), as JSON text.
// `cases`: the accuracy report's --cases (empty: all; the stability sweep has none).
std::string bench_manifest(const std::string& bench, bool quick, int parts, const std::string& cases = "");

// Runs the part into `dir` (its stability.csv and log); fills the job's outcome: "ok" or
// "failed" with the error, state_hash a digest of the part's rows.
void run_bench_part(const BenchPart& part, const std::filesystem::path& dir, nlohmann::json& outcome);

// After the summary: for each benchmark whose parts are in jobs.json, when every part is ok,
// DIR/bench/NAME/ gets the joined sweep; a part missing or failed is reported and nothing is
// joined for that benchmark. Returns false when a benchmark could not be joined.
bool merge_bench_parts(const std::filesystem::path& out_dir, const nlohmann::json& jobs_file, std::ostream& progress);

}  // namespace incise::batch
