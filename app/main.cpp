// The `incise` command: replay (headless), check, run (window), trajectory tools.
#include "app/command_line.hpp"
#include "app/commands.hpp"
#include "bench/accuracy.hpp"
#include "bench/haptics.hpp"
#include "bench/performance.hpp"
#include "bench/performance_report.hpp"
#include "bench/needle.hpp"
#include "bench/soak.hpp"
#include "bench/stability.hpp"

#include <CLI/CLI.hpp>

#include <cstdio>
#include <iostream>

#ifdef __GLIBC__
#include <malloc.h>
#endif

namespace {

void keep_freed_memory_in_the_heap() {
#ifdef __GLIBC__
  // The step loops allocate and free scratch of a few megabytes (per-vertex arrays of a large
  // surface at a cut event). By default glibc hands such blocks back to the kernel at each free
  // (mmap, heap trimming) and the next step takes them again page fault by page fault; kept in
  // the heap, a step reuses the pages the last one touched. (At 20k elements / 232k triangles:
  // 372k page faults over a 120-step replay against 218k.)
  mallopt(M_MMAP_THRESHOLD, 256 << 20);
  mallopt(M_TRIM_THRESHOLD, 512 << 20);
#endif
}

// The command given, run: the first that was given, in this order (`batch merge` before
// `batch`, which a merge also sets).
int run_command(const incise::app::Commands& c) {
  namespace app = incise::app;
  namespace bench = incise::bench;
  if (*c.replay.command) return app::replay(c.replay.args);
  if (*c.batch.merge_command) return app::batch_merge(c.batch.merge_dir);
  if (*c.batch.command) return app::batch_run(c.batch.args);
  if (*c.check.command) return app::check(c.check.scene);
  if (*c.run.command) return app::run(c.run.args);
  if (*c.session.command) return app::session(c.session.args);
  if (*c.report.command) return app::report(c.report.run_dir);
  if (*c.haptics.command) return bench::run_haptics_bench(c.haptics.options(), std::cerr);
  if (*c.soak.command) return bench::run_soak_bench(c.soak.options(), std::cerr);
  if (*c.needle.command) return bench::run_needle_bench(c.needle.options, std::cerr);
  const auto& t = c.trajectory;
  if (*t.export_command) return app::trajectory_export(t.export_file, t.export_out);
  if (*t.info_command) return app::trajectory_info(t.info_file);
  if (*t.import_command) return app::trajectory_import(t.import_file, t.import_out);
  if (*t.synth_command) return app::trajectory_synth(t.synth);
  const auto& accuracy = c.accuracy;
  if (*accuracy.command && !accuracy.manifest.empty())
    return app::emit_bench_manifest("accuracy", accuracy.quick, accuracy.parts, accuracy.manifest, accuracy.cases);
  if (*accuracy.command) {
    bench::AccuracyOptions options;
    options.quick = accuracy.quick;
    options.cases = accuracy.cases;
    return bench::run_accuracy_bench(options, accuracy.out, std::cerr);
  }
  const auto& stability = c.stability;
  if (*stability.command && !stability.manifest.empty())
    return app::emit_bench_manifest("stability", stability.quick, stability.parts, stability.manifest);
  if (*stability.command) return bench::run_stability_bench({stability.quick, stability.resume}, stability.out, std::cerr);
  const auto& performance = c.performance;
  if (*performance.command && performance.report_only) {
    std::printf("report: %s\n", bench::write_performance_report(performance.out, std::cerr).c_str());
    return 0;
  }
  if (*performance.command)
    return bench::run_performance_bench(performance.quick, performance.out, std::cerr, performance.backend, performance.preconditioner,
                                        {performance.multigrid_smoothing, performance.multigrid_precision});
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  keep_freed_memory_in_the_heap();
  CLI::App app{"incise: an interactive surgical simulator for practising incisions on soft organs.\n"
               "Headless replay of recorded tool trajectories with off-screen capture, scene checks,\n"
               "and the interactive window. See README.md and docs/ for the scene and trajectory formats."};
  app.require_subcommand(1);
  app.set_version_flag("--version", "incise 0.1.0");
  incise::app::Commands commands;
  incise::app::add_commands(app, commands);
  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    return app.exit(e);
  }
  try {
    return run_command(commands);
  } catch (const std::exception& e) {
    std::fprintf(stderr, "incise: %s\n", e.what());
    return 1;
  }
}
