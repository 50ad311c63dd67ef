// The subcommands of `incise`, one function each; command_line.cpp sets up their options and
// main.cpp parses the command line and calls the one given.
#pragma once

#include <array>
#include <optional>
#include <string>
#include <vector>

namespace incise::app {

struct ReplayArgs {
  std::string scene;
  std::string trajectory;
  std::string out = "out/replay";
  std::optional<int> capture_every;
  std::string size;
  std::optional<long> steps;
  std::string backend;    // overrides solver.backend
  std::string precision;  // overrides solver.precision
  bool check = false;
  bool quiet = false;
  bool report = false;  // write out/report.html at the end (incise report)
};

struct RunArgs {
  std::string scene;
  long frames = 0;
  std::string screenshot;
  std::string device = "virtual";  // virtual (mouse), replay (--play FILE), udp (a bridge)
  std::string play;                // replay device: the trajectory it plays
  std::string record;              // record every haptic tick to this trajectory file
  std::string udp_bind = "127.0.0.1";
  int udp_port = 0;
  std::string script_drag;         // tests: a scripted mouse drag "x0,y0,x1,y1" in window pixels
};

// `incise session`: the haptic loop and physics headless on simulated time, a scripted virtual
// device following a trajectory (the scene's tool.trajectory or --trajectory).
struct SessionArgs {
  std::string scene;
  std::string trajectory;
  std::optional<long> steps;
  std::string record;
  std::string out = "out/session";
  bool no_engage = false;
  bool quiet = false;
  bool report = false;  // write out/report.html at the end (incise report)
};

struct SynthArgs {
  std::string out;
  std::vector<double> contact{0, 0, 0.04};
  double depth = 0.008;
  std::vector<double> stroke{0.03, 0, 0};
  double rate_hz = 1000;
  double approach_seconds = 0.5, press_seconds = 0.3, hold_seconds = 0.2, stroke_seconds = 1.0,
         release_seconds = 0.5;
  double approach_height = 0.04;  // m above the contact point
};

// `incise batch`: a manifest's jobs, this process's shard of them (app/batch.cpp).
struct BatchArgs {
  std::string manifest;
  std::string out = "out/batch";
  std::string shard;  // "I/N"; empty: every job (or this MPI rank's shard)
  bool list = false;  // check the manifest and print its jobs; run nothing
};

int replay(const ReplayArgs& args);
int batch_run(const BatchArgs& args);
int batch_merge(const std::string& dir);
// `incise bench NAME --emit-manifest FILE --parts N`: the sweep as a batch manifest.
int emit_bench_manifest(const std::string& bench, bool quick, int parts, const std::string& file,
                        const std::string& cases = "");
int check(const std::string& scene_file);
int run(const RunArgs& args);
int session(const SessionArgs& args);
// `incise report RUN_DIR`: writes RUN_DIR/report.html and prints its path.
int report(const std::string& run_dir);
int trajectory_export(const std::string& file, const std::string& out);
int trajectory_info(const std::string& file);
int trajectory_import(const std::string& csv, const std::string& out);
int trajectory_synth(const SynthArgs& args);

}  // namespace incise::app
