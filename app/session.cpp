// `incise session`: a haptic session headless on simulated time. A scripted virtual device
// follows a trajectory tick by tick while the 1 kHz loop renders forces from the ContactModel
// physics publishes each step, exactly as in the window but deterministic; --record writes
// every tick, which `incise replay --trajectory FILE --steps N` reproduces (same state hash).
#include "app/commands.hpp"

#include "engine/haptic_session.hpp"
#include "engine/replay.hpp"
#include "engine/incision_score.hpp"
#include "engine/scene.hpp"
#include "engine/trajectory.hpp"
#include "haptics/virtual_device.hpp"

#include <nlohmann/json.hpp>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <fstream>

namespace incise::app {

int session(const SessionArgs& args) {
  const engine::Scene scene = engine::load_scene(args.scene);
  if (!scene.tool) throw std::runtime_error(args.scene + ": the scene has no tool to drive");
  std::filesystem::path script_file = args.trajectory;
  if (script_file.empty()) {
    if (!scene.tool->trajectory) throw std::runtime_error(args.scene + ": no tool.trajectory: pass --trajectory FILE");
    script_file = *scene.tool->trajectory;
  }
  const engine::Trajectory script = engine::read_trajectory(script_file);
  if (script.samples.empty()) throw std::runtime_error(script_file.string() + ": holds no sample");
  if (!script.report.complete) std::fprintf(stderr, "warning: %s: %s\n", script_file.c_str(), script.report.problem.c_str());
  if (args.steps && *args.steps < 0) throw std::runtime_error("--steps must be >= 0");
  const long steps = args.steps ? *args.steps : std::lround(scene.solver.duration / scene.solver.dt);

  haptics::VirtualDevice device;
  engine::SessionOptions options;
  options.budget = scene.solver.realtime;
  options.keep_ticks = true;
  if (!args.record.empty()) options.record = args.record;
  options.script = [&](double t) {
    const engine::ToolSample s = engine::sample_at(script.samples, t);
    haptics::DevicePose pose;
    pose.position = s.position;
    pose.orientation = s.orientation;
    pose.buttons = args.no_engage ? 0 : (s.buttons & engine::kToolButtonEngaged);
    device.set_pose(pose);
  };
  engine::HapticSession run(scene, device, options);
  std::vector<engine::StepStats> step_stats;
  step_stats.reserve(static_cast<std::size_t>(std::max(0L, steps)));
  for (long k = 0; k < steps; ++k) step_stats.push_back(run.step());
  run.stop();

  const auto& world = run.world();
  nlohmann::json report = engine::session_summary(run);
  report["script"] = script_file.string();
  report["record"] = args.record;
  std::filesystem::create_directories(args.out);
  if (scene.plan) {
    const engine::IncisionScore score = engine::score_incision(*scene.plan, world, step_stats, scene.solver.dt);
    report["score"] = engine::score_json(score);
    engine::write_score_files(args.out, *scene.plan, score);
  }
  const auto file = std::filesystem::path(args.out) / "session.json";
  std::ofstream out(file);
  out << report.dump(2) << "\n";
  out.close();  // before --report reads it back
  if (!out) throw std::runtime_error(file.string() + ": cannot write");
  // The same per-step table as a replay's, for the report's plots.
  engine::write_steps_csv(std::filesystem::path(args.out) / "steps.csv", step_stats, scene.solver.dt);
  if (!args.record.empty()) engine::write_session_summary(run, args.record + ".json");
  if (!args.quiet) {
    std::printf("session %s: %llu steps, %zu ticks, %ld cut events, %s triangles, max |F| %.3f N\n", scene.name.c_str(),
                static_cast<unsigned long long>(world.steps_taken()), run.ticks().size(), world.cut_totals().events,
                report["surface_triangles"].dump().c_str(), report["max_force_N"].get<double>());
    std::printf("force jump N/ms: at cut %.4f (%s ticks), other publications %.4f, between %.4f\n",
                report["force_jump_at_cut_N_per_ms"]["max"].get<double>(),
                report["force_jump_at_cut_N_per_ms"]["ticks"].dump().c_str(),
                report["force_jump_at_other_publications_N_per_ms"]["max"].get<double>(),
                report["force_jump_between_publications_N_per_ms"]["max"].get<double>());
    std::printf("state_hash %s\n", report["state_hash"].get<std::string>().c_str());
    if (!args.record.empty())
      std::printf("recorded %llu ticks to %s (summary %s.json); check: incise replay %s --trajectory %s --steps %llu\n",
                  static_cast<unsigned long long>(run.samples_recorded()), args.record.c_str(), args.record.c_str(),
                  args.scene.c_str(), args.record.c_str(), static_cast<unsigned long long>(world.steps_taken()));
    std::printf("report: %s\n", file.c_str());
  }
  if (args.report) return app::report(args.out);
  return 0;
}

}  // namespace incise::app
