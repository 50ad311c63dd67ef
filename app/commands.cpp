#include "app/commands.hpp"

#include "engine/model_registry.hpp"
#include "engine/replay.hpp"
#include "engine/scene.hpp"
#include "engine/trajectory.hpp"
#include "engine/trajectory_synth.hpp"
#include "engine/world.hpp"
#include "report/run_report.hpp"

#include <cstdio>
#include <fstream>
#include <iostream>

namespace incise::app {

namespace {

std::pair<int, int> parse_size(const std::string& text) {
  int w = 0, h = 0;
  char extra = 0;
  if (std::sscanf(text.c_str(), "%5dx%5d%c", &w, &h, &extra) != 2)
    throw std::runtime_error("--size: '" + text + "' is not WxH (e.g. 640x480)");
  if (w < 16 || h < 16 || w > 8192 || h > 8192)
    throw std::runtime_error("--size: " + text + " must be within 16x16 and 8192x8192");
  return {w, h};
}

// The registered models and what each can do: "fem (corotational ...), efg (..., cuttable, gpu)".
std::string model_list() {
  std::string text;
  for (const auto& m : engine::models().entries()) {
    std::string traits = m.summary;
    if (m.cuttable) traits += std::string(traits.empty() ? "" : ", ") + "cuttable";
    if (m.gpu) traits += std::string(traits.empty() ? "" : ", ") + "gpu";
    text += (text.empty() ? "" : ", ") + m.name + (traits.empty() ? "" : " (" + traits + ")");
  }
  return text;
}

}  // namespace

int replay(const ReplayArgs& args) {
  engine::Scene scene = engine::load_scene(args.scene);
  if (!args.backend.empty()) scene.solver.backend = args.backend;
  if (!args.precision.empty()) scene.solver.precision = args.precision;
  engine::ReplayOptions options;
  options.out_dir = args.out;
  if (!args.trajectory.empty()) options.trajectory = args.trajectory;
  if (args.capture_every) {
    if (*args.capture_every < 0) throw std::runtime_error("--capture-every must be >= 0");
    options.capture_every = args.capture_every;
  }
  if (!args.size.empty()) options.size = parse_size(args.size);
  if (args.steps) {
    if (*args.steps < 0) throw std::runtime_error("--steps must be >= 0");
    options.steps = args.steps;
  }
  options.progress = !args.quiet;
  auto result = engine::run_replay(scene, options);
  const auto& m = result.metrics;
  if (!args.quiet) {
    std::printf("scene %s: %s steps, %.3f s simulated in %.2f s; ms/step median %.2f p95 %.2f max %.2f; "
                "CG iterations mean %.1f max %s\n",
                scene.name.c_str(), m["steps"].dump().c_str(), m["sim_time_s"].get<double>(),
                m["wall_time_s"].get<double>(), m["ms_per_step"]["median"].get<double>(),
                m["ms_per_step"]["p95"].get<double>(), m["ms_per_step"]["max"].get<double>(),
                m["cg_iterations"]["mean"].get<double>(), m["cg_iterations"]["max"].dump().c_str());
    std::printf("state_hash %s\n", m["state_hash"].get<std::string>().c_str());
    std::printf("metrics: %s\n", (options.out_dir / "metrics.json").string().c_str());
    if (m.contains("frames"))
      std::printf("frames:  %s (%s PNG)\n", m["frames"]["dir"].get<std::string>().c_str(),
                  m["frames"]["count"].dump().c_str());
    if (m.contains("trajectory") && m["trajectory"].is_object() && !m["trajectory"]["complete"].get<bool>())
      std::fprintf(stderr, "warning: trajectory damaged: %s\n",
                   m["trajectory"]["problem"].get<std::string>().c_str());
  }
  // Also after a failed run: the page shows what was recorded and the error.
  if (args.report) report(options.out_dir.string());
  if (!result.ok) {
    std::fprintf(stderr, "incise: replay stopped: %s (metrics kept in %s)\n",
                 m["error"].get<std::string>().c_str(), (options.out_dir / "metrics.json").string().c_str());
    return 1;
  }
  if (args.check) {
    int failed = 0;
    for (const auto& r : engine::check_expectations(scene, m)) {
      std::string bounds = std::string(r.min ? "min " + std::to_string(*r.min) : "") +
                           (r.min && r.max ? ", " : "") + (r.max ? "max " + std::to_string(*r.max) : "");
      std::printf("%s %s = %s (%s)\n", r.passed ? "pass" : "FAIL", r.metric.c_str(),
                  r.value ? std::to_string(*r.value).c_str() : "missing", bounds.c_str());
      failed += r.passed ? 0 : 1;
    }
    if (scene.expect.empty()) std::printf("the scene has no `expect` block: nothing to check\n");
    if (failed) {
      std::fprintf(stderr, "incise: %d expectation(s) failed\n", failed);
      return 1;
    }
  }
  return 0;
}

int report(const std::string& run_dir) {
  const auto page = report::write_run_report(run_dir, std::cerr);
  std::printf("report: %s\n", page.string().c_str());
  return 0;
}

int check(const std::string& scene_file) {
  engine::Scene scene = engine::load_scene(scene_file);
  std::optional<engine::Trajectory> trajectory;
  if (scene.tool && scene.tool->trajectory) {
    trajectory = engine::read_trajectory(*scene.tool->trajectory);
    if (!trajectory->report.complete)
      std::fprintf(stderr, "warning: %s: %s\n", scene.tool->trajectory->string().c_str(),
                   trajectory->report.problem.c_str());
  }
  engine::World world(scene, std::move(trajectory));
  std::printf("%s: ok (scene '%s')\n", scene_file.c_str(), scene.name.c_str());
  std::printf("  models: %s\n", model_list().c_str());
  for (std::size_t i = 0; i < world.bodies().size(); ++i) {
    const auto& body = world.bodies()[i];
    const engine::ModelEntry* model = engine::models().find(body.model->kind);
    const std::string nodes = model ? model->node_name + "s" : std::string("nodes");
    int fixed = 0;
    for (auto f : body.data.fixed) fixed += f;
    std::printf("  body %s (%s%s): %d %s, %zu elements, %d fixed %s, %zu surface triangles\n",
                body.model->name.c_str(), body.model->kind.c_str(), scene.bodies[i].cuttable ? ", cuttable" : "",
                body.data.mechanics->node_count(), nodes.c_str(), body.model->elements, fixed, nodes.c_str(),
                body.data.surface.size());
    const engine::BuildTimes& t = body.build_ms;
    std::printf("    built in %.0f ms: shape %.0f, volume %.0f, surface %.0f, cut %.0f, settle %.0f\n", t.total, t.shape,
                t.volume, t.surface, t.cut, t.settle);
    if (body.model->snap.boundary_nodes > 0)
      std::printf("    surface snapping: %d boundary nodes, %d moved onto the surface, %d part way, %d left; "
                  "smallest element keeps %.0f %% of its volume\n",
                  body.model->snap.boundary_nodes, body.model->snap.moved, body.model->snap.moved_partly, body.model->snap.left,
                  100 * body.model->snap.min_volume_ratio);
  }
  if (world.tool().present) {
    std::printf("  tool: %s, radius %.4g m", scene.tool->shape.c_str(), scene.tool->radius);
    if (world.needle_count() > 1) std::printf(", %zu needles (tool.needles)", world.needle_count());
    std::printf("\n");
  }
  return 0;
}

int trajectory_export(const std::string& file, const std::string& out) {
  auto trajectory = engine::read_trajectory(file);
  if (!trajectory.report.complete) std::fprintf(stderr, "warning: %s: %s\n", file.c_str(), trajectory.report.problem.c_str());
  if (out.empty()) {
    engine::export_csv(trajectory, std::cout);
  } else {
    std::ofstream stream(out);
    if (!stream) throw std::runtime_error(out + ": cannot open for writing");
    engine::export_csv(trajectory, stream);
  }
  return trajectory.report.complete ? 0 : 2;
}

int trajectory_import(const std::string& csv, const std::string& out) {
  std::ifstream in(csv);
  if (!in) throw std::runtime_error(csv + ": cannot open");
  const auto samples = engine::import_csv(in, csv);
  engine::write_trajectory(out, samples);
  std::printf("%s: %zu samples, %.3f .. %.3f s\n", out.c_str(), samples.size(), samples.front().time, samples.back().time);
  return 0;
}

int trajectory_info(const std::string& file) {
  auto trajectory = engine::read_trajectory(file);
  const auto& s = trajectory.samples;
  std::printf("%s: %zu samples in %zu chunks", file.c_str(), s.size(), trajectory.report.chunks_read);
  if (!s.empty()) std::printf(", t = %.6f .. %.6f s", s.front().time, s.back().time);
  std::printf("\n");
  // Recorded in real time: the CGs the budget stopped, which a replay repeats.
  if (!trajectory.cg_stops.empty())
    std::printf("%zu CG stops recorded over steps %llu .. %llu (a replay repeats them)\n", trajectory.cg_stops.size(),
                static_cast<unsigned long long>(trajectory.cg_stops.front().step),
                static_cast<unsigned long long>(trajectory.cg_stops.back().step));
  const auto& report = trajectory.report;
  if (!report.complete) {
    // A torn tail is what a crash while recording leaves (the chunk being written when the
    // process died); anything else is damage to bytes that were written whole.
    if (report.torn_tail)
      std::printf("torn tail: %zu complete chunks kept; %zu bytes of a torn chunk after byte %llu were dropped\n",
                  report.chunks_read, report.bytes_discarded, static_cast<unsigned long long>(report.discarded_from));
    else
      std::printf("damaged: %zu complete chunks kept; %zu bytes after byte %llu were dropped\n", report.chunks_read,
                  report.bytes_discarded, static_cast<unsigned long long>(report.discarded_from));
    std::printf("why: %s\n", report.problem.c_str());
    return 2;
  }
  std::printf("complete\n");
  return 0;
}

int trajectory_synth(const SynthArgs& args) {
  if (args.contact.size() != 3) throw std::runtime_error("--contact takes x,y,z");
  if (args.stroke.size() != 3) throw std::runtime_error("--stroke takes x,y,z");
  engine::PokeSpec spec;
  spec.contact_point = {args.contact[0], args.contact[1], args.contact[2]};
  spec.approach_point = {args.contact[0], args.contact[1], args.contact[2] + args.approach_height};
  spec.depth = args.depth;
  spec.stroke = {args.stroke[0], args.stroke[1], args.stroke[2]};
  spec.rate_hz = args.rate_hz;
  spec.approach_seconds = args.approach_seconds;
  spec.press_seconds = args.press_seconds;
  spec.hold_seconds = args.hold_seconds;
  spec.stroke_seconds = args.stroke_seconds;
  spec.release_seconds = args.release_seconds;
  auto samples = engine::synthesize_poke(spec);
  engine::write_trajectory(args.out, samples);
  std::printf("%s: %zu samples, %.3f s\n", args.out.c_str(), samples.size(), samples.back().time);
  return 0;
}

}  // namespace incise::app
