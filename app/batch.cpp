// `incise batch MANIFEST --out DIR [--shard I/N]` and `incise batch merge DIR` (docs/batch.md).
#include "app/commands.hpp"

#include "batch/bench_job.hpp"
#include "batch/json_file.hpp"
#include "batch/manifest.hpp"
#include "batch/merge.hpp"
#include "batch/ranks.hpp"
#include "batch/runner.hpp"

#include <cstdio>
#include <iostream>

namespace incise::app {

namespace {

// The shard this process runs: --shard, or its MPI rank (a rank's shard is rank/size).
batch::Shard choose_shard(const BatchArgs& args, const batch::Ranks& ranks) {
  if (ranks.size() > 1) {
    if (!args.shard.empty())
      throw std::runtime_error("--shard: under mpirun each rank takes its own shard; leave --shard out");
    return {ranks.rank(), ranks.size()};
  }
  return args.shard.empty() ? batch::Shard{} : batch::parse_shard(args.shard);
}

int report_merge(const batch::MergeTotals& totals) {
  if (totals.failed + totals.missing == 0) {
    if (totals.benches_joined) return 0;
    std::fprintf(stderr, "incise batch: a benchmark's parts could not be joined (see above)\n");
    return 1;
  }
  std::fprintf(stderr, "incise batch: %d of %d jobs failed, %d not run (summary.csv has their errors)\n",
               totals.failed, totals.jobs, totals.missing);
  return 1;
}

int run_shard(const BatchArgs& args, batch::Ranks& ranks) {
  const batch::Manifest manifest = batch::read_manifest(args.manifest);
  const batch::Shard shard = choose_shard(args, ranks);
  const batch::BatchTotals totals = batch::run_batch(manifest, args.out, shard, std::cerr);
  std::fprintf(stderr, "shard %d/%d: %d jobs, %d run, %d finished before, %d failed\n", shard.index, shard.count,
               totals.jobs, totals.ran, totals.skipped, totals.failed);
  // One process that ran every job merges at once; separate shards (Slurm's array) are merged
  // by `incise batch merge` when all are done, mpirun's ranks by rank 0 after the barrier.
  ranks.barrier();
  if (shard.count == 1 || (ranks.size() > 1 && ranks.rank() == 0)) return report_merge(batch::merge_batch(args.out, std::cerr));
  return totals.failed > 0 ? 1 : 0;
}

// --list: the expanded jobs, one a line, so that a grid can be seen (and a Slurm array sized)
// before anything runs.
int list_jobs(const std::string& manifest_file) {
  const batch::Manifest manifest = batch::read_manifest(manifest_file);
  for (std::size_t i = 0; i < manifest.jobs.size(); ++i) {
    const batch::Job& job = manifest.jobs[i];
    std::string overrides;
    for (const auto& [key, value] : job.overrides) overrides += " " + key + "=" + value.dump();
    const std::string what = job.bench ? "bench " + job.bench->name + " part " + std::to_string(job.bench->part) + "/" +
                                             std::to_string(job.bench->parts)
                                       : job.scene.filename().string();
    std::printf("%zu %s %s%s\n", i, job.name.c_str(), what.c_str(), overrides.c_str());
  }
  std::printf("%s: %zu jobs\n", manifest_file.c_str(), manifest.jobs.size());
  return 0;
}

}  // namespace

int batch_run(const BatchArgs& args) {
  if (args.manifest.empty()) throw std::runtime_error("batch: a MANIFEST (or `merge DIR`) is required");
  if (args.list) return list_jobs(args.manifest);
  batch::Ranks ranks;
  try {
    return run_shard(args, ranks);
  } catch (const std::exception& e) {
    if (ranks.size() == 1) throw;
    std::fprintf(stderr, "incise: rank %d: %s\n", ranks.rank(), e.what());
    ranks.abort(1);
  }
}

int batch_merge(const std::string& dir) { return report_merge(batch::merge_batch(dir, std::cerr)); }

int emit_bench_manifest(const std::string& bench, bool quick, int parts, const std::string& file,
                        const std::string& cases) {
  batch::write_atomically(file, batch::bench_manifest(bench, quick, parts, cases));
  std::fprintf(stderr, "wrote %s: %s in %d parts; run it with `incise batch %s --out DIR` (or its shards), then "
               "`incise batch merge DIR` joins the sweep into DIR/bench/%s/\n",
               file.c_str(), bench.c_str(), parts, file.c_str(), bench.c_str());
  return 0;
}

}  // namespace incise::app
