// Headless replay: a scene and a recorded trajectory in; frames, metrics and a state hash out.
//
// Threads: the physics thread steps the World on simulated time (a deterministic
// scheduler: step k covers (t_{k-1}, t_k] and takes every tool sample in it), the render
// thread owns the off-screen GL context and turns every K-th snapshot into a PNG, and the
// calling thread only draws the progress bar. Rendering never feeds back into physics, so
// two replays of the same scene give the same state hash.
#pragma once

#include "engine/scene.hpp"
#include "engine/world.hpp"

#include <nlohmann/json.hpp>

#include <filesystem>
#include <optional>
#include <string>
#include <vector>

namespace incise::engine {

struct ReplayOptions {
  std::filesystem::path out_dir = "out/replay";
  std::optional<std::filesystem::path> trajectory;  // overrides tool.trajectory
  std::optional<int> capture_every;                 // overrides render.capture_every
  std::optional<std::pair<int, int>> size;          // overrides render.size
  std::optional<long> steps;                        // overrides solver.duration / dt
  bool progress = false;                            // draw a progress bar on stderr
};

struct ReplayResult {
  nlohmann::json metrics;
  bool ok = true;  // false when the run stopped on an error (metrics.error says which)
};

// Runs the replay and writes out_dir/metrics.json (also when the run fails midway, so
// nothing recorded is lost). Throws only for errors found before the first step (bad
// trajectory file, scene that cannot be built, output folder not writable).
ReplayResult run_replay(const Scene& scene, const ReplayOptions& options);

struct ExpectationResult {
  std::string metric;
  std::optional<double> value;  // absent when the metric is missing or not a number
  std::optional<double> min, max;
  bool passed = false;
};

// steps.csv: one row per step (phase times, CG, tool force, energies, cut figures) for plots
// and review; a replay and a session both write it. Throws std::runtime_error naming the file.
void write_steps_csv(const std::filesystem::path& file, const std::vector<StepStats>& stats, double dt);

// Checks the scene's `expect` block against metrics.
std::vector<ExpectationResult> check_expectations(const Scene& scene, const nlohmann::json& metrics);

// Looks up a dotted path ("positions_digest.centroid.2") in a JSON document.
std::optional<double> metric_value(const nlohmann::json& metrics, const std::string& path);

}  // namespace incise::engine
