// The command line of `incise`: per command, what it reads and the function that adds its
// options (app/command_line.cpp); main.cpp parses and hands each command to its function in
// commands.hpp or bench/.
#pragma once

#include "app/commands.hpp"
#include "bench/haptics.hpp"
#include "bench/needle.hpp"
#include "bench/soak.hpp"

#include <CLI/CLI.hpp>

#include <optional>
#include <string>

namespace incise::app {

// Each `command` is the subcommand its add function made: true once parsed when it was given.
struct ReplayCommand {
  ReplayArgs args;
  CLI::App* command = nullptr;
};

struct CheckCommand {
  std::string scene;
  CLI::App* command = nullptr;
};

struct RunCommand {
  RunArgs args;
  CLI::App* command = nullptr;
};

struct SessionCommand {
  SessionArgs args;
  CLI::App* command = nullptr;
};

struct ReportCommand {
  std::string run_dir;
  CLI::App* command = nullptr;
};

// `incise trajectory export|info|import|synth`.
struct TrajectoryCommands {
  std::string export_file, export_out;
  bool export_csv = false;
  CLI::App* export_command = nullptr;
  std::string info_file;
  CLI::App* info_command = nullptr;
  std::string import_file, import_out;
  CLI::App* import_command = nullptr;
  SynthArgs synth;
  CLI::App* synth_command = nullptr;
};

// `incise batch` and `incise batch merge DIR`.
struct BatchCommand {
  BatchArgs args;
  CLI::App* command = nullptr;
  std::string merge_dir;
  CLI::App* merge_command = nullptr;
};

struct AccuracyBenchCommand {
  bool quick = false;
  std::string out = "out/bench/accuracy";
  std::string manifest;  // --emit-manifest: write the report's runs as a batch manifest instead
  int parts = 4;
  std::string cases;  // --cases: a subset of the report
  CLI::App* command = nullptr;
};

struct StabilityBenchCommand {
  bool quick = false, resume = false;
  std::string out = "out/bench/stability";
  std::string manifest;  // --emit-manifest: write the sweep as a batch manifest instead
  int parts = 8;
  CLI::App* command = nullptr;
};

struct PerformanceBenchCommand {
  bool quick = false;
  std::string out = "out/bench/performance";
  std::string preconditioner = "all";
  int multigrid_smoothing = 0;       // 0: the scene's
  std::string multigrid_precision;  // "": the scene's
  bool report_only = false;
  std::string backend = "cpu";
  CLI::App* command = nullptr;
};

// `incise bench haptics`: its options, read into HapticsBenchOptions once parsed.
struct HapticsBenchCommand {
  bench::HapticsBenchOptions defaults;
  std::string scene;
  bool normal_priority = false;
  bool no_pin = false;
  CLI::App* command = nullptr;

  bench::HapticsBenchOptions options() const {
    bench::HapticsBenchOptions o = defaults;
    o.scene = scene;
    o.realtime_priority = !normal_priority;
    o.pin = !no_pin;
    return o;
  }
};

// `incise bench soak`: its options, read into SoakOptions once parsed.
struct SoakBenchCommand {
  bench::SoakOptions defaults;
  double minutes = 30;
  std::optional<double> seconds;
  std::string scene;
  double rss_limit_percent = 100 * defaults.rss_growth_limit;
  CLI::App* command = nullptr;

  bench::SoakOptions options() const {
    bench::SoakOptions o = defaults;
    o.seconds = seconds ? *seconds : 60 * minutes;
    o.scene = scene;
    o.rss_growth_limit = rss_limit_percent / 100;
    return o;
  }
};

// `incise bench needle`.
struct NeedleBenchCommand {
  bench::NeedleBenchOptions options;
  CLI::App* command = nullptr;
};

struct Commands {
  ReplayCommand replay;
  CheckCommand check;
  RunCommand run;
  SessionCommand session;
  ReportCommand report;
  TrajectoryCommands trajectory;
  BatchCommand batch;
  AccuracyBenchCommand accuracy;
  StabilityBenchCommand stability;
  PerformanceBenchCommand performance;
  HapticsBenchCommand haptics;
  SoakBenchCommand soak;
  NeedleBenchCommand needle;
};

// Adds every command to `app`, bound to `commands` (which must outlive the parse), in the
// order --help lists them.
void add_commands(CLI::App& app, Commands& commands);

}  // namespace incise::app
