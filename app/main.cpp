// The `incise` command: replay (headless), check, run (window), trajectory tools.
#include "app/commands.hpp"
#include "bench/accuracy.hpp"
#include "bench/haptics.hpp"
#include "bench/performance.hpp"
#include "bench/performance_report.hpp"
#include "bench/soak.hpp"
#include "bench/stability.hpp"

#include <CLI/CLI.hpp>

#include <cstdio>
#include <iostream>
#include <optional>

#ifdef __GLIBC__
#include <malloc.h>
#endif

namespace {

// `incise bench soak`: its options, read into SoakOptions once parsed.
struct SoakCommand {
  incise::bench::SoakOptions defaults;
  double minutes = 30;
  std::optional<double> seconds;
  std::string scene;
  double rss_limit_percent = 100 * defaults.rss_growth_limit;

  incise::bench::SoakOptions options() const {
    incise::bench::SoakOptions o = defaults;
    o.seconds = seconds ? *seconds : 60 * minutes;
    o.scene = scene;
    o.rss_growth_limit = rss_limit_percent / 100;
    return o;
  }
};

CLI::App* add_soak_command(CLI::App& bench, SoakCommand& soak) {
  auto* command = bench.add_subcommand(
      "soak", "A long haptic session on the lobe: random strokes cut, lift, cut again, bodies rebuilt; RSS must stay flat");
  auto* minutes = command->add_option("--minutes", soak.minutes, "How long (fractions allowed)")->capture_default_str();
  command->add_option("--seconds", soak.seconds, "How long in seconds (instead of --minutes)")->excludes(minutes);
  command->add_option("--out", soak.defaults.out_dir, "Output folder (soak.csv, soak.png)")->capture_default_str();
  command->add_option("--scene", soak.scene, "Scene (default assets/scenes/default.json)");
  command->add_option("--seed", soak.defaults.seed, "Seed of the strokes")->capture_default_str();
  command->add_option("--rss-limit", soak.rss_limit_percent, "RSS growth after the warm-up that fails the verdict, % of the warm-up's peak")
      ->check(CLI::Range(0.0, 1000.0))
      ->capture_default_str();
  return command;
}

}  // namespace

int main(int argc, char** argv) {
#ifdef __GLIBC__
  // The step loops allocate and free scratch of a few megabytes (per-vertex arrays of a large
  // surface at a cut event). By default glibc hands such blocks back to the kernel at each free
  // (mmap, heap trimming) and the next step takes them again page fault by page fault; kept in
  // the heap, a step reuses the pages the last one touched. (At 20k elements / 232k triangles:
  // 372k page faults over a 120-step replay against 218k.)
  mallopt(M_MMAP_THRESHOLD, 256 << 20);
  mallopt(M_TRIM_THRESHOLD, 512 << 20);
#endif
  CLI::App app{"incise: an interactive surgical simulator for practising incisions on soft organs.\n"
               "Headless replay of recorded tool trajectories with off-screen capture, scene checks,\n"
               "and the interactive window. See README.md and docs/ for the scene and trajectory formats."};
  app.require_subcommand(1);
  app.set_version_flag("--version", "incise 0.1.0");

  incise::app::ReplayArgs replay;
  auto* replay_cmd = app.add_subcommand("replay", "Replay a scene headless on simulated time; write metrics.json and frames");
  replay_cmd->add_option("scene", replay.scene, "Scene file (JSON)")->required();
  replay_cmd->add_option("--trajectory", replay.trajectory, "Tool trajectory file (overrides tool.trajectory)");
  replay_cmd->add_option("--out", replay.out, "Output folder (metrics.json, frames/)")->capture_default_str();
  replay_cmd->add_option("--capture-every", replay.capture_every, "Capture a frame every K steps (0: none; default from render.capture_every)");
  replay_cmd->add_option("--size", replay.size, "Frame size WxH, e.g. 640x480 (default from render.size)");
  replay_cmd->add_option("--steps", replay.steps, "Number of steps (default: solver.duration / solver.dt)");
  replay_cmd->add_option("--backend", replay.backend, "Deformation backend, overrides solver.backend")
      ->check(CLI::IsMember({"cpu", "gpu"}));
  replay_cmd->add_option("--precision", replay.precision, "GPU precision, overrides solver.precision")
      ->check(CLI::IsMember({"single", "double"}));
  replay_cmd->add_flag("--check", replay.check, "Check the scene's `expect` block; exit 1 when one fails");
  replay_cmd->add_flag("--quiet", replay.quiet, "No progress bar or summary");
  replay_cmd->add_flag("--report", replay.report, "Write OUT/report.html (and OUT/replay.mp4) at the end, as `incise report OUT`");

  std::string check_scene;
  auto* check_cmd = app.add_subcommand("check", "Validate a scene file and build its world; exit non-zero on any error");
  check_cmd->add_option("scene", check_scene, "Scene file (JSON)")->required();

  incise::app::RunArgs run;
  auto* run_cmd = app.add_subcommand("run", "Open the interactive window on a scene");
  run_cmd->add_option("scene", run.scene, "Scene file (JSON)")->required();
  run_cmd->add_option("--frames", run.frames, "Close after this many frames (0: when the window closes)");
  run_cmd->add_option("--screenshot", run.screenshot, "Save a PNG of the last frame");
  run_cmd->add_option("--device", run.device, "Tool input: virtual (the mouse), replay (--play FILE) or udp (a bridge)")
      ->check(CLI::IsMember({"virtual", "replay", "udp"}))
      ->capture_default_str();
  run_cmd->add_option("--play", run.play, "Trajectory the replay device plays");
  run_cmd->add_option("--record", run.record, "Record every haptic tick (pose, buttons, force, device state) to this trajectory file");
  run_cmd->add_option("--udp-bind", run.udp_bind, "udp device: address to bind")->capture_default_str();
  run_cmd->add_option("--udp-port", run.udp_port, "udp device: port (0: any free one, printed)")->capture_default_str();
  run_cmd->add_option("--script-drag", run.script_drag, "Tests: drag the mouse from x0,y0 to x1,y1 (pixels) with the blade engaged");

  incise::app::SessionArgs session;
  auto* session_cmd = app.add_subcommand("session", "A haptic session headless on simulated time: a scripted virtual device follows a trajectory; --record writes every tick");
  session_cmd->add_option("scene", session.scene, "Scene file (JSON)")->required();
  session_cmd->add_option("--trajectory", session.trajectory, "What the scripted device follows (default: tool.trajectory)");
  session_cmd->add_option("--steps", session.steps, "Number of physics steps (default: solver.duration / solver.dt)");
  session_cmd->add_option("--record", session.record, "Record every tick to this trajectory file");
  session_cmd->add_option("--out", session.out, "Output folder (session.json)")->capture_default_str();
  session_cmd->add_flag("--no-engage", session.no_engage, "Never engage the blade (the same strokes without cutting)");
  session_cmd->add_flag("--quiet", session.quiet, "No summary");
  session_cmd->add_flag("--report", session.report, "Write OUT/report.html at the end, as `incise report OUT`");

  std::string report_dir;
  auto* report_cmd = app.add_subcommand("report", "Write RUN_DIR/report.html: the scene, video, frames, plots, score, expectations and metrics of a run");
  report_cmd->add_option("run_dir", report_dir, "A replay's or session's output folder (holds metrics.json or session.json)")->required();

  auto* trajectory_cmd = app.add_subcommand("trajectory", "Inspect, export or synthesise tool trajectory files");
  trajectory_cmd->require_subcommand(1);
  std::string export_file, export_out;
  bool export_csv = false;
  auto* export_cmd = trajectory_cmd->add_subcommand("export", "Write a trajectory as text for people");
  export_cmd->add_option("file", export_file, "Trajectory file")->required();
  export_cmd->add_flag("--csv", export_csv, "CSV (the only format for now)");
  export_cmd->add_option("--out", export_out, "Output file (default: standard output)");
  std::string info_file;
  auto* info_cmd = trajectory_cmd->add_subcommand("info", "Summarise a trajectory file and report damage");
  info_cmd->add_option("file", info_file, "Trajectory file")->required();
  std::string import_file, import_out;
  auto* import_cmd = trajectory_cmd->add_subcommand("import", "Write a trajectory file from CSV (the export's columns)");
  import_cmd->add_option("csv", import_file, "CSV: time,x,y,z,qw,qx,qy,qz,buttons[,fx,fy,fz]")->required();
  import_cmd->add_option("--out", import_out, "Output trajectory file")->required();
  incise::app::SynthArgs synth;
  auto* synth_cmd = trajectory_cmd->add_subcommand("synth", "Synthesise a probe poke or a blade stroke (approach, press, slide, lift)");
  synth_cmd->add_option("--out", synth.out, "Output trajectory file")->required();
  synth_cmd->add_option("--contact", synth.contact, "Contact point on the surface x,y,z (m)")->delimiter(',');
  synth_cmd->add_option("--depth", synth.depth, "Press depth (m)")->capture_default_str();
  synth_cmd->add_option("--stroke", synth.stroke, "Lateral stroke while pressed x,y,z (m)")->delimiter(',');
  synth_cmd->add_option("--rate", synth.rate_hz, "Samples per second")->capture_default_str();
  synth_cmd->add_option("--approach-height", synth.approach_height, "Start this far above the contact point (m)")->capture_default_str();
  synth_cmd->add_option("--approach-seconds", synth.approach_seconds, "Duration of the approach")->capture_default_str();
  synth_cmd->add_option("--press-seconds", synth.press_seconds, "Duration of the press")->capture_default_str();
  synth_cmd->add_option("--hold-seconds", synth.hold_seconds, "Duration of the hold")->capture_default_str();
  synth_cmd->add_option("--stroke-seconds", synth.stroke_seconds, "Duration of the stroke")->capture_default_str();
  synth_cmd->add_option("--release-seconds", synth.release_seconds, "Duration of the release")->capture_default_str();

  incise::app::BatchArgs batch;
  auto* batch_cmd = app.add_subcommand("batch", "Run a manifest's jobs (replays, sweeps of scene overrides) as shards or MPI ranks; see docs/batch.md");
  batch_cmd->add_option("manifest", batch.manifest, "Batch manifest (JSON)");
  batch_cmd->add_option("--out", batch.out, "Output folder (jobs/NAME/, jobs.json, summary.csv, summary.png)")->capture_default_str();
  batch_cmd->add_option("--shard", batch.shard, "Run the I-th of N interleaved slices of the jobs, e.g. 0/4");
  batch_cmd->add_flag("--list", batch.list, "Check the manifest and print its jobs (index, name, overrides); run nothing");
  std::string merge_dir;
  auto* merge_cmd = batch_cmd->add_subcommand("merge", "Gather a batch's outcomes into DIR/summary.csv and summary.png");
  merge_cmd->add_option("dir", merge_dir, "The batch's --out folder")->required();

  auto* bench_cmd = app.add_subcommand("bench", "Benchmarks that print figures and write reports (CSV, PNG)");
  bench_cmd->require_subcommand(1);
  bool accuracy_quick = false, stability_quick = false, stability_resume = false;
  std::string accuracy_out = "out/bench/accuracy", stability_out = "out/bench/stability";
  auto* accuracy_cmd = bench_cmd->add_subcommand("accuracy", "Error against run time per step, per model, variant and resolution");
  accuracy_cmd->add_flag("--quick", accuracy_quick, "A smaller sweep (about 3 minutes here)");
  accuracy_cmd->add_option("--out", accuracy_out, "Output folder (accuracy.csv, accuracy.png, references.json)")->capture_default_str();
  auto* stability_cmd = bench_cmd->add_subcommand("stability", "Stiff and extreme cases: outcome per model, integrator, case, E, nu, dt");
  stability_cmd->add_flag("--quick", stability_quick, "A representative subset (within 3 minutes here)");
  stability_cmd->add_option("--out", stability_out, "Output folder (stability.csv, stability.png)")->capture_default_str();
  stability_cmd->add_flag("--resume", stability_resume,
                          "Keep the runs already in OUT/stability.csv (an interrupted sweep) and run the missing ones");
  std::string stability_manifest;
  int stability_parts = 8;
  stability_cmd->add_option("--emit-manifest", stability_manifest,
                            "Write a batch manifest of the sweep in --parts jobs instead of running it (docs/batch.md)");
  stability_cmd->add_option("--parts", stability_parts, "Jobs of the emitted manifest")
      ->check(CLI::Range(1, 10000))
      ->capture_default_str();

  bool performance_quick = false;
  std::string performance_out = "out/bench/performance";
  auto* performance_cmd = bench_cmd->add_subcommand("performance", "Step time by phase while cutting, by element and triangle count");
  performance_cmd->add_flag("--quick", performance_quick, "Two resolutions only: the coarsest and 20k elements");
  performance_cmd->add_option("--out", performance_out, "Output folder (performance.csv)")->capture_default_str();
  std::string performance_preconditioner = "all";
  performance_cmd->add_option("--preconditioner", performance_preconditioner,
                              "CG's preconditioner: all side by side, or two_level, warped_cholesky or jacobi (the Jacobi CG) alone")
      ->check(CLI::IsMember({"all", "two_level", "warped_cholesky", "jacobi"}))
      ->capture_default_str();
  bool performance_report_only = false;
  performance_cmd->add_flag("--report-only", performance_report_only,
                            "Run nothing: write OUT/report.html from the OUT/performance.csv already there");
  std::string performance_backend = "cpu";
  performance_cmd->add_option("--backend", performance_backend, "gpu: also run every size on the GPU backend")
      ->check(CLI::IsMember({"cpu", "gpu"}))
      ->capture_default_str();

  incise::bench::HapticsBenchOptions haptics_bench;
  std::string haptics_scene;
  auto* haptics_cmd = bench_cmd->add_subcommand("haptics", "The 1 kHz loop against a cutting scene while physics runs, with and without cutting, beside a bare loop");
  haptics_cmd->add_option("--seconds", haptics_bench.seconds, "Seconds per run (three runs)")->capture_default_str();
  haptics_cmd->add_option("--out", haptics_bench.out_dir, "Output folder (haptics.json)")->capture_default_str();
  haptics_cmd->add_option("--scene", haptics_scene, "Cutting scene (default assets/scenes/haptics_block.json)");
  haptics_cmd->add_option("--spin-us", haptics_bench.spin_us, "Sleep to this long before each deadline, then spin")->capture_default_str();
  haptics_cmd->add_option("--record", haptics_bench.record,
                          "Record the cutting run's ticks and CG stops to this trajectory file (incise replay repeats it)");
  bool haptics_normal_priority = false;
  haptics_cmd->add_flag("--normal-priority", haptics_normal_priority,
                        "Run the loops at normal priority (as where SCHED_FIFO is refused)");

  SoakCommand soak;
  CLI::App* soak_cmd = add_soak_command(*bench_cmd, soak);

  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    return app.exit(e);
  }

  try {
    if (*replay_cmd) return incise::app::replay(replay);
    if (*merge_cmd) return incise::app::batch_merge(merge_dir);
    if (*batch_cmd) return incise::app::batch_run(batch);
    if (*check_cmd) return incise::app::check(check_scene);
    if (*run_cmd) return incise::app::run(run);
    if (*session_cmd) return incise::app::session(session);
    if (*report_cmd) return incise::app::report(report_dir);
    if (*haptics_cmd) {
      haptics_bench.scene = haptics_scene;
      haptics_bench.realtime_priority = !haptics_normal_priority;
      return incise::bench::run_haptics_bench(haptics_bench, std::cerr);
    }
    if (*soak_cmd) return incise::bench::run_soak_bench(soak.options(), std::cerr);
    if (*export_cmd) return incise::app::trajectory_export(export_file, export_out);
    if (*info_cmd) return incise::app::trajectory_info(info_file);
    if (*import_cmd) return incise::app::trajectory_import(import_file, import_out);
    if (*synth_cmd) return incise::app::trajectory_synth(synth);
    if (*accuracy_cmd) return incise::bench::run_accuracy_bench(accuracy_quick, accuracy_out, std::cerr);
    if (*stability_cmd && !stability_manifest.empty())
      return incise::app::emit_bench_manifest("stability", stability_quick, stability_parts, stability_manifest);
    if (*stability_cmd) return incise::bench::run_stability_bench({stability_quick, stability_resume}, stability_out, std::cerr);
    if (*performance_cmd && performance_report_only) {
      std::printf("report: %s\n", incise::bench::write_performance_report(performance_out, std::cerr).c_str());
      return 0;
    }
    if (*performance_cmd) return incise::bench::run_performance_bench(performance_quick, performance_out, std::cerr, performance_backend,
                                                                     performance_preconditioner);
  } catch (const std::exception& e) {
    std::fprintf(stderr, "incise: %s\n", e.what());
    return 1;
  }
  return 0;
}
