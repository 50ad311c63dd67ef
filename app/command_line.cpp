#include "app/command_line.hpp"

namespace incise::app {

namespace {

void add_replay_command(CLI::App& app, ReplayCommand& replay) {
  ReplayArgs& args = replay.args;
  auto* command = app.add_subcommand("replay", "Replay a scene headless on simulated time; write metrics.json and frames");
  command->add_option("scene", args.scene, "Scene file (JSON)")->required();
  command->add_option("--trajectory", args.trajectory, "Tool trajectory file (overrides tool.trajectory)");
  command->add_option("--out", args.out, "Output folder (metrics.json, frames/)")->capture_default_str();
  command->add_option("--capture-every", args.capture_every, "Capture a frame every K steps (0: none; default from render.capture_every)");
  command->add_option("--size", args.size, "Frame size WxH, e.g. 640x480 (default from render.size)");
  command->add_option("--steps", args.steps, "Number of steps (default: solver.duration / solver.dt)");
  command->add_option("--backend", args.backend, "Deformation backend, overrides solver.backend")
      ->check(CLI::IsMember({"cpu", "gpu"}));
  command->add_option("--precision", args.precision, "GPU precision, overrides solver.precision")
      ->check(CLI::IsMember({"single", "double"}));
  command->add_flag("--check", args.check, "Check the scene's `expect` block; exit 1 when one fails");
  command->add_flag("--quiet", args.quiet, "No progress bar or summary");
  command->add_flag("--report", args.report, "Write OUT/report.html (and OUT/replay.mp4) at the end, as `incise report OUT`");
  replay.command = command;
}

void add_check_command(CLI::App& app, CheckCommand& check) {
  check.command = app.add_subcommand("check", "Validate a scene file and build its world; exit non-zero on any error");
  check.command->add_option("scene", check.scene, "Scene file (JSON)")->required();
}

void add_run_command(CLI::App& app, RunCommand& run) {
  RunArgs& args = run.args;
  auto* command = app.add_subcommand("run", "Open the interactive window on a scene");
  command->add_option("scene", args.scene, "Scene file (JSON)")->required();
  command->add_option("--frames", args.frames, "Close after this many frames (0: when the window closes)");
  command->add_option("--screenshot", args.screenshot, "Save a PNG of the last frame");
  command->add_option("--device", args.device, "Tool input: virtual (the mouse), replay (--play FILE) or udp (a bridge)")
      ->check(CLI::IsMember({"virtual", "replay", "udp"}))
      ->capture_default_str();
  command->add_option("--play", args.play, "Trajectory the replay device plays");
  command->add_option("--record", args.record, "Record every haptic tick (pose, buttons, force, device state) to this trajectory file");
  command->add_option("--udp-bind", args.udp_bind, "udp device: address to bind")->capture_default_str();
  command->add_option("--udp-port", args.udp_port, "udp device: port (0: any free one, printed)")->capture_default_str();
  command->add_option("--script-drag", args.script_drag, "Tests: drag the mouse from x0,y0 to x1,y1 (pixels) with the blade engaged");
  run.command = command;
}

void add_session_command(CLI::App& app, SessionCommand& session) {
  SessionArgs& args = session.args;
  auto* command = app.add_subcommand("session", "A haptic session headless on simulated time: a scripted virtual device follows a trajectory; --record writes every tick");
  command->add_option("scene", args.scene, "Scene file (JSON)")->required();
  command->add_option("--trajectory", args.trajectory, "What the scripted device follows (default: tool.trajectory)");
  command->add_option("--steps", args.steps, "Number of physics steps (default: solver.duration / solver.dt)");
  command->add_option("--record", args.record, "Record every tick to this trajectory file");
  command->add_option("--out", args.out, "Output folder (session.json)")->capture_default_str();
  command->add_flag("--no-engage", args.no_engage, "Never engage the blade (the same strokes without cutting)");
  command->add_flag("--quiet", args.quiet, "No summary");
  command->add_flag("--report", args.report, "Write OUT/report.html at the end, as `incise report OUT`");
  session.command = command;
}

void add_report_command(CLI::App& app, ReportCommand& report) {
  report.command = app.add_subcommand("report", "Write RUN_DIR/report.html: the scene, video, frames, plots, score, expectations and metrics of a run");
  report.command->add_option("run_dir", report.run_dir, "A replay's or session's output folder (holds metrics.json or session.json)")->required();
}

void add_synth_command(CLI::App& trajectory, TrajectoryCommands& commands) {
  SynthArgs& synth = commands.synth;
  auto* command = trajectory.add_subcommand("synth", "Synthesise a probe poke or a blade stroke (approach, press, slide, lift)");
  command->add_option("--out", synth.out, "Output trajectory file")->required();
  command->add_option("--contact", synth.contact, "Contact point on the surface x,y,z (m)")->delimiter(',');
  command->add_option("--depth", synth.depth, "Press depth (m)")->capture_default_str();
  command->add_option("--stroke", synth.stroke, "Lateral stroke while pressed x,y,z (m)")->delimiter(',');
  command->add_option("--rate", synth.rate_hz, "Samples per second")->capture_default_str();
  command->add_option("--approach-height", synth.approach_height, "Start this far above the contact point (m)")->capture_default_str();
  command->add_option("--approach-seconds", synth.approach_seconds, "Duration of the approach")->capture_default_str();
  command->add_option("--press-seconds", synth.press_seconds, "Duration of the press")->capture_default_str();
  command->add_option("--hold-seconds", synth.hold_seconds, "Duration of the hold")->capture_default_str();
  command->add_option("--stroke-seconds", synth.stroke_seconds, "Duration of the stroke")->capture_default_str();
  command->add_option("--release-seconds", synth.release_seconds, "Duration of the release")->capture_default_str();
  commands.synth_command = command;
}

void add_trajectory_commands(CLI::App& app, TrajectoryCommands& commands) {
  auto* trajectory = app.add_subcommand("trajectory", "Inspect, export or synthesise tool trajectory files");
  trajectory->require_subcommand(1);
  auto* export_command = trajectory->add_subcommand("export", "Write a trajectory as text for people");
  export_command->add_option("file", commands.export_file, "Trajectory file")->required();
  export_command->add_flag("--csv", commands.export_csv, "CSV (the only format for now)");
  export_command->add_option("--out", commands.export_out, "Output file (default: standard output)");
  commands.export_command = export_command;
  commands.info_command = trajectory->add_subcommand("info", "Summarise a trajectory file and report damage");
  commands.info_command->add_option("file", commands.info_file, "Trajectory file")->required();
  auto* import_command = trajectory->add_subcommand("import", "Write a trajectory file from CSV (the export's columns)");
  import_command->add_option("csv", commands.import_file, "CSV: time,x,y,z,qw,qx,qy,qz,buttons[,fx,fy,fz]")->required();
  import_command->add_option("--out", commands.import_out, "Output trajectory file")->required();
  commands.import_command = import_command;
  add_synth_command(*trajectory, commands);
}

void add_batch_command(CLI::App& app, BatchCommand& batch) {
  BatchArgs& args = batch.args;
  auto* command = app.add_subcommand("batch", "Run a manifest's jobs (replays, sweeps of scene overrides) as shards or MPI ranks; see docs/batch.md");
  command->add_option("manifest", args.manifest, "Batch manifest (JSON)");
  command->add_option("--out", args.out, "Output folder (jobs/NAME/, jobs.json, summary.csv, summary.png)")->capture_default_str();
  command->add_option("--shard", args.shard, "Run the I-th of N interleaved slices of the jobs, e.g. 0/4");
  command->add_flag("--list", args.list, "Check the manifest and print its jobs (index, name, overrides); run nothing");
  batch.command = command;
  batch.merge_command = command->add_subcommand("merge", "Gather a batch's outcomes into DIR/summary.csv and summary.png");
  batch.merge_command->add_option("dir", batch.merge_dir, "The batch's --out folder")->required();
}

void add_accuracy_command(CLI::App& parent, AccuracyBenchCommand& accuracy) {
  auto* command = parent.add_subcommand("accuracy", "Error against run time per step, per model, variant and resolution");
  command->add_flag("--quick", accuracy.quick, "A smaller sweep (about 3 minutes here)");
  command->add_option("--out", accuracy.out, "Output folder (accuracy.csv, accuracy.png, references.json)")->capture_default_str();
  command->add_option("--cases", accuracy.cases,
                      "Only these cases, comma-separated (bend, stretch, bend_cut, stretch_cut, b1, traction, compression)");
  command->add_option("--emit-manifest", accuracy.manifest,
                      "Write a batch manifest of the runs in --parts jobs instead of running them (docs/batch.md)");
  command->add_option("--parts", accuracy.parts, "Jobs of the emitted manifest (5 units of work: more leave parts empty)")
      ->check(CLI::Range(1, 10000))
      ->capture_default_str();
  accuracy.command = command;
}

void add_stability_command(CLI::App& parent, StabilityBenchCommand& stability) {
  auto* command = parent.add_subcommand("stability", "Stiff and extreme cases: outcome per model, integrator, case, E, nu, dt");
  command->add_flag("--quick", stability.quick, "A representative subset (within 3 minutes here)");
  command->add_option("--out", stability.out, "Output folder (stability.csv, stability.png)")->capture_default_str();
  command->add_flag("--resume", stability.resume,
                    "Keep the runs already in OUT/stability.csv (an interrupted sweep) and run the missing ones");
  command->add_option("--emit-manifest", stability.manifest,
                      "Write a batch manifest of the sweep in --parts jobs instead of running it (docs/batch.md)");
  command->add_option("--parts", stability.parts, "Jobs of the emitted manifest")
      ->check(CLI::Range(1, 10000))
      ->capture_default_str();
  stability.command = command;
}

void add_performance_command(CLI::App& parent, PerformanceBenchCommand& performance) {
  auto* command = parent.add_subcommand("performance", "Step time by phase while cutting, by element and triangle count");
  command->add_flag("--quick", performance.quick, "Two resolutions only: the coarsest and 20k elements");
  command->add_option("--out", performance.out, "Output folder (performance.csv)")->capture_default_str();
  command->add_option("--preconditioner", performance.preconditioner,
                      "CG's preconditioner: all side by side, or multigrid, multigrid_current, two_level, warped_cholesky or jacobi (the Jacobi CG) alone")
      ->check(CLI::IsMember({"all", "multigrid", "multigrid_current", "two_level", "warped_cholesky", "jacobi"}))
      ->capture_default_str();
  command->add_option("--multigrid-smoothing", performance.multigrid_smoothing,
                      "The multigrid smoother's degree (scene solver.multigrid_smoothing; default: the scene's, else 2 for multigrid and 4 for multigrid_current)")
      ->check(CLI::Range(1, 8));
  command->add_option("--multigrid-precision", performance.multigrid_precision,
                      "The multigrid smoother's copy of the rest system (scene solver.multigrid_precision; default: the scene's)")
      ->check(CLI::IsMember({"double", "float"}));
  command->add_flag("--report-only", performance.report_only,
                    "Run nothing: write OUT/report.html from the OUT/performance.csv already there");
  command->add_option("--backend", performance.backend, "gpu: also run every size on the GPU backend")
      ->check(CLI::IsMember({"cpu", "gpu"}))
      ->capture_default_str();
  performance.command = command;
}

void add_haptics_command(CLI::App& parent, HapticsBenchCommand& haptics) {
  bench::HapticsBenchOptions& options = haptics.defaults;
  auto* command = parent.add_subcommand("haptics", "The 1 kHz loop against a cutting scene while physics runs, with and without cutting, beside a bare loop");
  command->add_option("--seconds", options.seconds, "Seconds per run (three runs)")->capture_default_str();
  command->add_option("--out", options.out_dir, "Output folder (haptics.json)")->capture_default_str();
  command->add_option("--scene", haptics.scene, "Cutting scene (default assets/scenes/haptics_block.json)");
  command->add_option("--spin-us", options.spin_us, "Sleep to this long before each deadline, then spin")->capture_default_str();
  command->add_option("--record", options.record,
                      "Record the cutting run's ticks and CG stops to this trajectory file (incise replay repeats it)");
  command->add_flag("--normal-priority", haptics.normal_priority,
                    "Run the loops at normal priority (as where SCHED_FIFO is refused)");
  command->add_option("--cpu", options.cpu,
                      "Pin the loop and the bare loops to this CPU (default: the last one the process may run on)");
  command->add_flag("--no-pin", haptics.no_pin, "Leave the loops unpinned (the scheduler places them)");
  haptics.command = command;
}

void add_soak_command(CLI::App& parent, SoakBenchCommand& soak) {
  auto* command = parent.add_subcommand(
      "soak", "A long haptic session on the lobe: random strokes cut, lift, cut again, bodies rebuilt; RSS must stay flat");
  auto* minutes = command->add_option("--minutes", soak.minutes, "How long (fractions allowed)")->capture_default_str();
  command->add_option("--seconds", soak.seconds, "How long in seconds (instead of --minutes)")->excludes(minutes);
  command->add_option("--out", soak.defaults.out_dir, "Output folder (soak.csv, soak.png)")->capture_default_str();
  command->add_option("--scene", soak.scene, "Scene (default assets/scenes/default.json)");
  command->add_option("--seed", soak.defaults.seed, "Seed of the strokes")->capture_default_str();
  command->add_option("--rss-limit", soak.rss_limit_percent, "RSS growth after the warm-up that fails the verdict, % of the warm-up's working size (its largest RSS)")
      ->check(CLI::Range(0.0, 1000.0))
      ->capture_default_str();
  soak.command = command;
}

void add_needle_command(CLI::App& parent, NeedleBenchCommand& needle) {
  auto* command = parent.add_subcommand("needle", "A needle into the shape-memory cube at three speeds: force against depth (puncture, insertion, retraction)");
  command->add_option("--out", needle.options.out_dir, "Output folder (needle.csv, needle.png)")->capture_default_str();
  command->add_option("--scene", needle.options.scene, "Needle scene (default assets/scenes/needle_cube.json)");
  needle.command = command;
}

void add_bench_commands(CLI::App& app, Commands& commands) {
  auto* bench = app.add_subcommand("bench", "Benchmarks that print figures and write reports (CSV, PNG)");
  bench->require_subcommand(1);
  add_accuracy_command(*bench, commands.accuracy);
  add_stability_command(*bench, commands.stability);
  add_performance_command(*bench, commands.performance);
  add_haptics_command(*bench, commands.haptics);
  add_soak_command(*bench, commands.soak);
  add_needle_command(*bench, commands.needle);
}

}  // namespace

void add_commands(CLI::App& app, Commands& commands) {
  add_replay_command(app, commands.replay);
  add_check_command(app, commands.check);
  add_run_command(app, commands.run);
  add_session_command(app, commands.session);
  add_report_command(app, commands.report);
  add_trajectory_commands(app, commands.trajectory);
  add_batch_command(app, commands.batch);
  add_bench_commands(app, commands);
}

}  // namespace incise::app
