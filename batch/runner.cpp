#include "batch/runner.hpp"

#include "batch/bench_job.hpp"
#include "batch/json_file.hpp"

#include "engine/replay.hpp"
#include "engine/scene.hpp"
#include "engine/scene_reader.hpp"

#include <chrono>
#include <cstdio>
#include <fstream>
#include <sstream>

namespace incise::batch {

namespace {

// The scene with the job's overrides applied to its JSON before the scene reader runs, so
// a bad value is refused naming the scene file and the field, as in the file itself.
engine::Scene scene_with_overrides(const Job& job) {
  std::ifstream in(job.scene, std::ios::binary);
  if (!in) throw engine::SceneError(job.scene.string(), {"cannot open the file"});
  std::stringstream text;
  text << in.rdbuf();
  std::vector<std::string> errors;
  Json root = engine::parse_scene_json(text.str(), errors);
  if (!errors.empty()) throw engine::SceneError(job.scene.string(), errors);
  for (const auto& [key, value] : job.overrides)
    if (const std::string problem = apply_override(root, key, value); !problem.empty())
      throw std::runtime_error("override \"" + key + "\": " + problem);
  return engine::parse_scene(root.dump(), job.scene);
}

// An error on one line ("a: 2 errors; a: b.c: ...; a: d: ..."), so that summary.csv keeps one
// line per job for grep, cut and spreadsheets.
std::string one_line(const std::string& text) {
  std::string line;
  for (std::size_t i = 0; i < text.size(); ++i) {
    if (text[i] != '\n') {
      line += text[i];
      continue;
    }
    while (i + 1 < text.size() && (text[i + 1] == ' ' || text[i + 1] == '\n')) ++i;
    line += "; ";
  }
  return line;
}

// Runs one job into `dir` and returns its outcome.json.
Json run_job(const Job& job, std::size_t index, const std::filesystem::path& dir, Shard shard) {
  const auto start = std::chrono::steady_clock::now();
  Json overrides = Json::object();
  for (const auto& [key, value] : job.overrides) overrides[key] = value;
  Json outcome = {{"job", job.name},       {"index", index},  {"scene", job.scene.string()},
                  {"overrides", overrides}, {"outcome", "ok"}, {"error", ""},
                  {"state_hash", ""},       {"steps", 0},     {"shard", std::to_string(shard.index) + "/" + std::to_string(shard.count)}};
  if (job.bench) outcome["scene"] = "bench " + job.bench->name;
  try {
    if (job.bench) {
      run_bench_part(*job.bench, dir, outcome);
      outcome["wall_s"] = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
      return outcome;
    }
    const engine::Scene scene = scene_with_overrides(job);
    engine::ReplayOptions options;
    options.out_dir = dir;
    options.trajectory = job.trajectory;
    options.capture_every = job.capture_every;
    options.steps = job.steps;
    const engine::ReplayResult result = engine::run_replay(scene, options);
    const Json& m = result.metrics;
    outcome["state_hash"] = m.value("state_hash", "");
    outcome["steps"] = m.value("steps", 0);
    outcome["replay_wall_s"] = m.value("wall_time_s", 0.0);
    outcome["ms_per_step_median"] = m["ms_per_step"].value("median", 0.0);
    if (m.contains("score")) outcome["score"] = m["score"];  // a scene with a plan (engine/incision_score.hpp)
    if (!result.ok) {
      outcome["outcome"] = "failed";
      outcome["error"] = one_line(m.value("error", "the replay stopped"));
    }
  } catch (const std::exception& e) {
    outcome["outcome"] = "failed";
    outcome["error"] = one_line(e.what());
  }
  outcome["wall_s"] = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  return outcome;
}

// DIR/jobs.json: written by every shard (the same text), compared when it is there already.
void write_jobs_file(const Manifest& manifest, const std::filesystem::path& out_dir) {
  const std::filesystem::path file = out_dir / "jobs.json";
  const Json jobs = jobs_json(manifest);
  if (std::filesystem::exists(file)) {
    const Json before = read_json_file(file);
    if (before.value("jobs", Json()) != jobs["jobs"])
      throw std::runtime_error(file.string() + ": this folder holds another batch (its jobs differ from " +
                               manifest.file.string() + "'s); choose another --out");
    return;
  }
  write_atomically(file, jobs.dump(2) + "\n");
}

}  // namespace

Shard parse_shard(const std::string& text) {
  Shard shard;
  char extra = 0;
  if (std::sscanf(text.c_str(), "%9d/%9d%c", &shard.index, &shard.count, &extra) != 2 || shard.count < 1 ||
      shard.index < 0 || shard.index >= shard.count)
    throw std::runtime_error("--shard: '" + text + "' is not I/N with 0 <= I < N (e.g. 0/4)");
  return shard;
}

BatchTotals run_batch(const Manifest& manifest, const std::filesystem::path& out_dir, Shard shard,
                      std::ostream& progress) {
  std::filesystem::create_directories(out_dir / "jobs");
  write_jobs_file(manifest, out_dir);
  BatchTotals totals;
  for (std::size_t i = 0; i < manifest.jobs.size(); ++i) {
    if (static_cast<int>(i % static_cast<std::size_t>(shard.count)) != shard.index) continue;
    const Job& job = manifest.jobs[i];
    const std::filesystem::path dir = out_dir / "jobs" / job.name;
    const std::filesystem::path outcome_file = dir / "outcome.json";
    ++totals.jobs;
    if (std::filesystem::exists(outcome_file)) {
      ++totals.skipped;
      if (read_json_file(outcome_file).value("outcome", "") != "ok") ++totals.failed;
      progress << "job " << i << " " << job.name << ": finished before, skipped\n";
      continue;
    }
    std::filesystem::create_directories(dir);
    const Json outcome = run_job(job, i, dir, shard);
    write_atomically(outcome_file, outcome.dump(2) + "\n");
    ++totals.ran;
    const bool ok = outcome["outcome"] == "ok";
    if (!ok) ++totals.failed;
    char line[160];
    std::snprintf(line, sizeof line, "job %zu %s: %s in %.2f s", i, job.name.c_str(), ok ? "ok" : "FAILED",
                  outcome["wall_s"].get<double>());
    progress << line << (ok ? " state_hash " + outcome["state_hash"].get<std::string>() : ": " + outcome["error"].get<std::string>())
             << "\n";
  }
  return totals;
}

}  // namespace incise::batch
