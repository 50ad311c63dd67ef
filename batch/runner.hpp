// Running a batch's jobs: each a headless replay into DIR/jobs/NAME/ (metrics.json,
// steps.csv, frames when asked) closed by outcome.json, the mark of a finished job.
#pragma once

#include "batch/manifest.hpp"

#include <filesystem>
#include <ostream>
#include <string>

namespace incise::batch {

// The I-th of N interleaved slices: the jobs whose index % count == index.
struct Shard {
  int index = 0;
  int count = 1;
};

// "I/N" with 0 <= I < N; throws std::runtime_error naming --shard otherwise.
Shard parse_shard(const std::string& text);

struct BatchTotals {
  int jobs = 0;     // in this shard
  int ran = 0;      // run now
  int skipped = 0;  // finished before (resume)
  int failed = 0;   // of the shard's jobs, run now or before
};

// Runs the shard's jobs that have no outcome.json yet; a job that fails records its error
// and the next one runs. Writes DIR/jobs.json first (the same from every shard) and refuses
// a DIR whose jobs.json lists other jobs (another manifest's batch).
BatchTotals run_batch(const Manifest& manifest, const std::filesystem::path& out_dir, Shard shard,
                      std::ostream& progress);

}  // namespace incise::batch
