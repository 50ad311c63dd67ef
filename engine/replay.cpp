#include "engine/replay.hpp"

#include "common/csv.hpp"
#include "common/percentile.hpp"
#include "common/progress_bar.hpp"
#include "engine/incision_score.hpp"
#include "engine/publication.hpp"
#include "engine/trajectory.hpp"
#include "engine/needle_summary.hpp"
#include "engine/world.hpp"
#include "physics/cp/constraint_particles.hpp"
#include "physics/gpu/efg_step.hpp"
#include "physics/promayon/promayon_body.hpp"
#include "render/image.hpp"
#include "render/offscreen.hpp"

#include <algorithm>
#include <set>
#include <atomic>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <iomanip>
#include <iostream>
#include <sstream>
#include <thread>
#include <unistd.h>

namespace incise::engine {

namespace {

using Clock = std::chrono::steady_clock;
using Json = nlohmann::json;
using common::percentile;

struct Snapshot {
  std::uint64_t step = 0;
  double time = 0;
  render::Frame frame;
};

std::string hex64(std::uint64_t v) {
  std::ostringstream out;
  out << "0x" << std::hex << std::setw(16) << std::setfill('0') << v;
  return out.str();
}

// The bar's text after the count: the simulated and the wall time.
std::string progress_text(double sim_time, double wall) {
  char text[96];
  std::snprintf(text, sizeof text, "steps  t = %.3f s  %.1f s wall", sim_time, wall);
  return text;
}

// The render thread: owns its GL context from creation to destruction.
class Capture {
 public:
  Capture(std::filesystem::path frames_dir, int width, int height)
      : frames_dir_(std::move(frames_dir)), width_(width), height_(height) {
    thread_ = std::thread([this] { run(); });
  }
  ~Capture() { finish(); }

  // Physics side: a slot to fill (waits while the render thread is a ring behind), or
  // nullptr when rendering failed and frames are no longer taken.
  Snapshot* begin() {
    while (!failed_.load(std::memory_order_acquire)) {
      if (Snapshot* slot = ring_.try_begin_push()) return slot;
      std::this_thread::sleep_for(std::chrono::microseconds(200));
    }
    return nullptr;
  }
  void end() { ring_.end_push(); }

  void finish() {
    if (!thread_.joinable()) return;
    done_.store(true, std::memory_order_release);
    thread_.join();
  }
  bool failed() const { return failed_.load(std::memory_order_acquire); }
  const std::string& error() const { return error_; }  // read after finish()
  const std::string& renderer() const { return renderer_; }
  long frames() const { return frames_; }
  double ms_render_median() const { return percentile(render_ms_, 0.5); }

 private:
  void run() {
    try {
      auto target = render::OffscreenTarget::create(width_, height_);
      renderer_ = target.renderer_string();
      for (;;) {
        Snapshot* s = ring_.front();
        if (!s) {
          if (done_.load(std::memory_order_acquire) && !ring_.front()) break;
          std::this_thread::sleep_for(std::chrono::microseconds(500));
          continue;
        }
        auto start = Clock::now();
        render::Image image = target.render(s->frame);
        char name[64];
        std::snprintf(name, sizeof name, "frame_%06llu.png", static_cast<unsigned long long>(s->step));
        render::write_png(frames_dir_ / name, image);
        render_ms_.push_back(std::chrono::duration<double, std::milli>(Clock::now() - start).count());
        ++frames_;
        ring_.pop();
      }
    } catch (const std::exception& e) {
      error_ = e.what();
      failed_.store(true, std::memory_order_release);
    }
  }

  std::filesystem::path frames_dir_;
  int width_, height_;
  SnapshotRing<Snapshot, 4> ring_;
  std::thread thread_;
  std::atomic<bool> done_{false};
  std::atomic<bool> failed_{false};
  std::string error_;
  std::string renderer_;
  long frames_ = 0;
  std::vector<double> render_ms_;
};

Json guards_json(const World& world) {
  Json events = Json::array();
  for (const auto& e : world.guard_events())
    events.push_back({{"step", e.step}, {"time_s", e.time}, {"body", e.body}, {"kind", e.kind}, {"detail", e.detail}});
  const auto& c = world.guard_counts();
  return {{"nonfinite_retries", c.nonfinite_retries},
          {"cg_not_converged", c.cg_not_converged},
          {"energy_growth", c.energy_growth},
          {"events", events},
          {"events_logged_max", World::kGuardLogLimit}};
}

}  // namespace

std::optional<double> metric_value(const Json& metrics, const std::string& path) {
  const Json* node = &metrics;
  std::size_t start = 0;
  while (start <= path.size()) {
    auto dot = path.find('.', start);
    std::string key = path.substr(start, dot == std::string::npos ? std::string::npos : dot - start);
    if (node->is_object()) {
      auto it = node->find(key);
      if (it == node->end()) return std::nullopt;
      node = &*it;
    } else if (node->is_array()) {
      char* end = nullptr;
      unsigned long index = std::strtoul(key.c_str(), &end, 10);
      if (key.empty() || *end != '\0' || index >= node->size()) return std::nullopt;
      node = &(*node)[index];
    } else {
      return std::nullopt;
    }
    if (dot == std::string::npos) break;
    start = dot + 1;
  }
  if (node->is_boolean()) return node->get<bool>() ? 1.0 : 0.0;
  if (!node->is_number()) return std::nullopt;
  return node->get<double>();
}

std::vector<ExpectationResult> check_expectations(const Scene& scene, const Json& metrics) {
  std::vector<ExpectationResult> results;
  for (const auto& e : scene.expect) {
    ExpectationResult r;
    r.metric = e.metric;
    r.min = e.min;
    r.max = e.max;
    r.value = metric_value(metrics, e.metric);
    r.passed = r.value && std::isfinite(*r.value) && (!e.min || *r.value >= *e.min) &&
               (!e.max || *r.value <= *e.max);
    results.push_back(r);
  }
  return results;
}

namespace {

// metrics.json `backend` {name, device, precision}: the device is the GL renderer string.
Json backend_json(const World& world) {
  for (const auto& body : world.bodies()) {
    if (!body.gpu) continue;
    return {{"name", "gpu"}, {"device", body.gpu->device()}, {"gl_version", body.gpu->gl_version()},
            {"precision", physics::gpu::precision_name(body.gpu->precision())}};
  }
  return {{"name", "cpu"}, {"device", "cpu"}, {"precision", "double"}};
}

// metrics.json `gpu`: what went up, over every body (physics/gpu/efg_step.hpp).
Json gpu_json(const World& world, const std::vector<StepStats>& stats) {
  physics::gpu::GpuCounters sum;
  long long full_row_bytes = 0;
  for (const auto& body : world.bodies()) {
    if (!body.gpu) continue;
    const auto& c = body.gpu->counters();
    sum.row_bytes += c.row_bytes;
    sum.row_batches += c.row_batches;
    sum.element_batches += c.element_batches;
    sum.incidence_batches += c.incidence_batches;
    sum.surface_batches += c.surface_batches;
    sum.state_bytes += c.state_bytes;
    sum.rotation_bytes += c.rotation_bytes;
    sum.reallocations += c.reallocations;
    sum.ms_upload += c.ms_upload;
    full_row_bytes += body.gpu->full_row_bytes();
  }
  long cut_steps = 0;
  long long cut_step_row_bytes = 0;
  for (const auto& s : stats) {
    if (!s.cut_event) continue;
    ++cut_steps;
    cut_step_row_bytes += s.gpu_row_bytes;
  }
  return {{"bytes_uploaded", sum.bytes_uploaded()},
          {"batches_uploaded", sum.row_batches},
          {"ms_upload", sum.ms_upload},
          {"row_bytes", sum.row_bytes},
          {"state_bytes", sum.state_bytes},
          {"rotation_bytes", sum.rotation_bytes},
          {"element_batches", sum.element_batches},
          {"incidence_batches", sum.incidence_batches},
          {"surface_batches", sum.surface_batches},
          {"reallocations", sum.reallocations},
          {"full_row_bytes", full_row_bytes},
          {"cut_steps", cut_steps},
          {"row_bytes_per_cut_step", cut_steps > 0 ? static_cast<double>(cut_step_row_bytes) / cut_steps : 0.0}};
}

// The trajectory the replay runs on (--trajectory, else the scene tool's; none without
// either) and its summary for metrics.json `trajectory` (null without one).
std::optional<Trajectory> load_trajectory(const Scene& scene, const ReplayOptions& options, Json& summary) {
  std::optional<Trajectory> trajectory;
  std::optional<std::filesystem::path> trajectory_file = options.trajectory;
  if (!trajectory_file && scene.tool) trajectory_file = scene.tool->trajectory;
  if (trajectory_file) trajectory = read_trajectory(*trajectory_file);
  summary = nullptr;
  if (trajectory) {
    summary = {{"file", trajectory_file->string()},
               {"samples", trajectory->samples.size()},
               {"chunks", trajectory->report.chunks_read},
               {"cg_stops", trajectory->cg_stops.size()},
               {"complete", trajectory->report.complete},
               {"problem", trajectory->report.problem}};
  }
  return trajectory;
}

long count_dofs(const World& world) {
  long dofs = 0;
  for (const auto& body : world.bodies()) dofs += 3L * body.data.mechanics->node_count();
  return dofs;
}

// What the replay does: the options where given, the scene's settings otherwise.
struct RunPlan {
  long steps = 0;
  int capture_every = 0;
  int width = 0, height = 0;
  std::filesystem::path frames_dir;
};

RunPlan plan_run(const Scene& scene, const ReplayOptions& options) {
  RunPlan plan;
  plan.steps = options.steps ? *options.steps : std::lround(scene.solver.duration / scene.solver.dt);
  plan.capture_every = options.capture_every ? *options.capture_every : scene.render.capture_every;
  plan.width = options.size ? options.size->first : scene.render.width;
  plan.height = options.size ? options.size->second : scene.render.height;
  plan.frames_dir = options.out_dir / "frames";
  return plan;
}

// The render thread, on a frames folder cleared of an earlier run's PNGs; none when the
// replay takes no frames.
std::unique_ptr<Capture> start_capture(const RunPlan& plan) {
  if (plan.capture_every <= 0) return nullptr;
  std::filesystem::create_directories(plan.frames_dir);
  for (const auto& entry : std::filesystem::directory_iterator(plan.frames_dir))
    if (entry.path().extension() == ".png") std::filesystem::remove(entry.path());
  return std::make_unique<Capture>(plan.frames_dir, plan.width, plan.height);
}

struct RunOutcome {
  std::vector<StepStats> stats;  // one per step taken
  std::string error;             // why the physics thread stopped early; empty when it did not
  double wall = 0;               // s, from the first step to the last frame written
};

// Steps the world on a physics thread, handing every capture_every-th state (and the
// initial one) to the render thread, while this thread draws the progress bar.
RunOutcome run_steps(World& world, const Scene& scene, const ReplayOptions& options, const RunPlan& plan,
                     Capture* capture) {
  RunOutcome run;
  auto& stats = run.stats;
  stats.reserve(static_cast<std::size_t>(std::max(0L, plan.steps)));
  std::atomic<long> steps_done{0};
  auto publish = [&](std::uint64_t step) {
    if (!capture) return;
    if (Snapshot* s = capture->begin()) {
      s->step = step;
      s->time = world.time();
      world.fill_frame(s->frame, plan.width, plan.height);
      capture->end();
    }
  };

  const auto wall_start = Clock::now();
  std::thread physics([&] {
    try {
      publish(0);
      for (long k = 1; k <= plan.steps; ++k) {
        stats.push_back(world.step());
        if (plan.capture_every > 0 && k % plan.capture_every == 0) publish(static_cast<std::uint64_t>(k));
        steps_done.store(k, std::memory_order_release);
      }
    } catch (const std::exception& e) {
      run.error = e.what();
    }
    steps_done.store(-1, std::memory_order_release);
  });
  const bool tty = options.progress && isatty(STDERR_FILENO);
  common::ProgressBar bar(std::cerr, plan.steps);
  while (steps_done.load(std::memory_order_acquire) >= 0) {
    std::this_thread::sleep_for(std::chrono::milliseconds(100));
    long done = steps_done.load(std::memory_order_acquire);
    if (tty && done >= 0) {
      bar.set_done(done);
      bar.draw(progress_text(static_cast<double>(done) * scene.solver.dt,
                             std::chrono::duration<double>(Clock::now() - wall_start).count()));
    }
  }
  physics.join();
  if (capture) capture->finish();
  run.wall = std::chrono::duration<double>(Clock::now() - wall_start).count();
  if (tty) {
    bar.set_done(static_cast<long>(stats.size()));
    bar.draw(progress_text(world.time(), run.wall));
    bar.finish();
  }
  return run;
}

// The steps' timings, solver iterations and tool figures, gathered for their summaries.
struct StepTotals {
  std::vector<double> total, tool_input, cut_phase, contact, solve, surface;
  double cg_sum = 0, cg_residual_max = 0, max_force = 0;
  int cg_max = 0, nonfinite = 0, not_converged = 0, budget_stopped = 0, contacts_max = 0;
  std::vector<double> per_iteration;
  std::string preconditioner = "jacobi";
  long long preconditioner_age_max = 0;
  double preconditioner_build_ms_max = 0, preconditioner_wait_ms = 0;
};

StepTotals gather_steps(const std::vector<StepStats>& stats) {
  StepTotals t;
  for (const auto& s : stats) {
    t.total.push_back(s.ms_total);
    t.tool_input.push_back(s.ms_tool_input);
    t.cut_phase.push_back(s.ms_ccd + s.ms_topology);
    t.contact.push_back(s.ms_contact);
    t.solve.push_back(s.ms_solve);
    t.surface.push_back(s.ms_surface);
    t.cg_sum += s.cg_iterations;
    t.cg_max = std::max(t.cg_max, s.cg_iterations);
    if (s.cg_iterations > 0) t.per_iteration.push_back(s.ms_solve / s.cg_iterations);
    t.preconditioner = s.preconditioner;
    t.preconditioner_age_max = std::max(t.preconditioner_age_max, s.preconditioner_age);
    t.preconditioner_build_ms_max = std::max(t.preconditioner_build_ms_max, s.preconditioner_build_ms);
    t.preconditioner_wait_ms += s.preconditioner_wait_ms;
    t.cg_residual_max = std::max(t.cg_residual_max, s.cg_residual);
    t.nonfinite += s.nonfinite_events;
    // A CG a recorded real-time stop ended is counted apart from one that ran out of iterations.
    t.not_converged += s.cg_converged || s.cg_budget_stops > 0 ? 0 : 1;
    t.budget_stopped += s.cg_budget_stops > 0 ? 1 : 0;
    t.contacts_max = std::max(t.contacts_max, s.contacts);
    t.max_force = std::max(t.max_force, std::sqrt(s.tool_force[0] * s.tool_force[0] +
                                                  s.tool_force[1] * s.tool_force[1] +
                                                  s.tool_force[2] * s.tool_force[2]));
  }
  return t;
}

// What the user sees moved: the surface vertices (nodes of a tetrahedral body; embedded
// vertices of a meshless one, whose particles may lie outside the body). Returns the largest
// displacement from rest; `vertices` receives their count.
double surface_max_displacement(const Body& body, std::size_t& vertices) {
  const auto& x = body.data.state.positions;
  const auto& rest = body.data.mechanics->rest_positions();
  double surface_max = 0;
  if (body.data.embedding) {
    physics::Vector rest_vertices;
    physics::CorotationalEfg::surface_positions(*body.data.embedding, rest, rest_vertices);
    const auto indices = static_cast<std::size_t>(body.data.embedding->vertex_count());
    vertices = indices;
    for (std::size_t v = 0; v < indices; ++v) {
      const auto at = static_cast<Eigen::Index>(3 * v);
      surface_max = std::max(surface_max, (body.data.surface_positions.segment<3>(at) - rest_vertices.segment<3>(at)).norm());
    }
  } else {
    vertices = body.model->surface_nodes.size();
    for (int node : body.model->surface_nodes)
      surface_max = std::max(surface_max, (x.segment<3>(3 * node) - rest.segment<3>(3 * node)).norm());
  }
  return surface_max;
}

// metrics.json `positions_digest`: over every node of every body, in body order.
struct PositionsDigest {
  std::array<double, 3> centroid{};
  double mean_displacement = 0, max_displacement = 0;
};

// metrics.json `bodies`; `digest` receives the positions digest, summed in the same pass.
Json build_ms_json(const BuildTimes& b) {
  return {{"total", b.total}, {"shape", b.shape}, {"volume", b.volume}, {"surface", b.surface},
          {"cut", b.cut}, {"settle", b.settle}};
}

Json bodies_json(const World& world, PositionsDigest& digest) {
  std::size_t nodes = 0;
  Json bodies = Json::array();
  for (const auto& body : world.bodies()) {
    const auto& x = body.data.state.positions;
    const auto& rest = body.data.mechanics->rest_positions();
    const int n = body.data.mechanics->node_count();
    for (int i = 0; i < n; ++i) {
      for (int c = 0; c < 3; ++c) digest.centroid[c] += x[3 * i + c];
      double d = (x.segment<3>(3 * i) - rest.segment<3>(3 * i)).norm();
      digest.mean_displacement += d;
      digest.max_displacement = std::max(digest.max_displacement, d);
    }
    nodes += static_cast<std::size_t>(n);
    int fixed = 0;
    for (auto f : body.data.fixed) fixed += f;
    std::size_t surface_vertices = 0;
    const double surface_max = surface_max_displacement(body, surface_vertices);
    Json entry = {{"name", body.model->name},
                  {"model", body.data.embedding ? std::string("efg_corotated")
                            : body.model->kind == "mass_spring" ? std::string("mass_spring_hex")
                            : body.model->kind == "constraint_particles" ? std::string("constraint_particles_tet")
                            : body.model->kind == "fem"         ? std::string("fem_corotational_tet4")
                                                                : body.model->kind},
                  {"surface_vertices", surface_vertices},
                  {"surface_max_displacement", surface_max},
                  {"nodes", n},
                  {"dofs", 3 * n},
                  {"elements", body.model->elements},
                  {"fixed_nodes", fixed},
                  {"surface_triangles", body.data.surface.size()},
                  {"build_ms", build_ms_json(body.build_ms)}};
    // Dionne's model: its volume over the rest volume (digest D3) and its inverted tets.
    if (const auto* particles = dynamic_cast<const physics::ConstraintParticles*>(body.data.mechanics.get())) {
      entry["volume_ratio"] = particles->volume(x) / particles->volume(rest);
      entry["inverted_tets"] = particles->inverted_tets(x);
    }
    // Promayon's volume control (seed 002 §1.5): how far the closed surface ever was from V0(t).
    const auto* promayon = dynamic_cast<const physics::PromayonBody*>(body.data.mechanics.get());
    if (promayon && promayon->volume()) {
      if (promayon->volume()->mode == physics::VolumeMode::exact)
        entry["volume_relative_error_max"] = promayon->worst_volume_error();
      entry["volume_m3"] = promayon->last_volume();
      entry["volume_target_m3"] = promayon->last_volume_target();
    }
    bodies.push_back(std::move(entry));
  }
  for (auto& c : digest.centroid) c /= static_cast<double>(std::max<std::size_t>(nodes, 1));
  digest.mean_displacement /= static_cast<double>(std::max<std::size_t>(nodes, 1));
  return bodies;
}

// metrics.json `build_ms`: the world's construction, every body's parts summed.
Json world_build_ms_json(const World& world) {
  BuildTimes sum;
  for (const auto& body : world.bodies()) {
    const BuildTimes& b = body.build_ms;
    sum.shape += b.shape;
    sum.volume += b.volume;
    sum.surface += b.surface;
    sum.cut += b.cut;
    sum.settle += b.settle;
    sum.total += b.total;
  }
  return build_ms_json(sum);
}

// metrics.json before the optional sections: the run, its timings, the solver, the state.
Json run_metrics(const Scene& scene, const World& world, const RunOutcome& run, const RunPlan& plan,
                 long dofs_initial, const Json& trajectory_json) {
  const auto& stats = run.stats;
  const StepTotals t = gather_steps(stats);
  PositionsDigest digest;
  const Json bodies = bodies_json(world, digest);
  const StepStats last = stats.empty() ? StepStats{} : stats.back();
  const long dofs_final = count_dofs(world);
  return {
      {"scene", scene.name},
      {"scene_file", scene.file.string()},
      {"backend", backend_json(world)},
      {"steps", stats.size()},
      {"steps_requested", plan.steps},
      {"dt_s", scene.solver.dt},
      {"sim_time_s", world.time()},
      {"wall_time_s", run.wall},
      {"ms_per_step", {{"median", percentile(t.total, 0.5)}, {"p95", percentile(t.total, 0.95)},
                       {"max", t.total.empty() ? 0 : *std::max_element(t.total.begin(), t.total.end())}}},
      {"phases_ms", {{"tool_input", percentile(t.tool_input, 0.5)}, {"cut", percentile(t.cut_phase, 0.5)}, {"contact", percentile(t.contact, 0.5)},
                     {"solve", percentile(t.solve, 0.5)}, {"surface", percentile(t.surface, 0.5)}}},
      {"cg_iterations", {{"mean", stats.empty() ? 0.0 : t.cg_sum / static_cast<double>(stats.size())},
                         {"max", t.cg_max}}},
      {"cg_residual_max", t.cg_residual_max},
      {"preconditioner", {{"kind", t.preconditioner},
                          {"ms_per_iteration_median", percentile(t.per_iteration, 0.5)},
                          {"age_max_steps", t.preconditioner_age_max},
                          {"build_ms_max", t.preconditioner_build_ms_max},
                          {"wait_ms_total", t.preconditioner_wait_ms}}},
      {"cg_not_converged_steps", t.not_converged},
      {"cg_budget_stopped_steps", t.budget_stopped},
      {"nonfinite_events", t.nonfinite},
      {"guards", guards_json(world)},
      {"energy_J", {{"elastic", last.elastic_energy}, {"kinetic", last.kinetic_energy}}},
      {"positions_digest", {{"centroid", digest.centroid},
                            {"mean_displacement", digest.mean_displacement},
                            {"max_displacement", digest.max_displacement}}},
      {"state_hash", hex64(world.state_hash())},
      {"motion_hash", hex64(world.motion_hash())},
      {"bodies", bodies},
      {"build_ms", world_build_ms_json(world)},
      {"tool", {{"max_force_N", t.max_force}, {"max_contacts", t.contacts_max}}},
      {"dofs", {{"initial", dofs_initial}, {"final", dofs_final}}},
      {"trajectory", trajectory_json},
  };
}

// metrics.json `frames`; a capture failure becomes the run's error unless it already has one.
void add_frames_metrics(Json& metrics, const Capture& capture, const RunPlan& plan, std::string& error) {
  metrics["frames"] = {{"count", capture.frames()},
                       {"every_steps", plan.capture_every},
                       {"dir", plan.frames_dir.string()},
                       {"size", {plan.width, plan.height}},
                       {"renderer", capture.renderer()},
                       {"ms_render_median", capture.ms_render_median()}};
  if (capture.failed()) {
    metrics["frames"]["error"] = capture.error();
    if (error.empty()) error = "off-screen capture failed: " + capture.error();
  }
}

bool any_cuttable(const World& world) {
  bool cuttable = false;
  for (const auto& body : world.bodies()) cuttable = cuttable || body.cut != nullptr;
  return cuttable;
}

// metrics.json `needle` (engine/needle_summary.hpp); the ratios are what a scene's expect
// block bounds: the puncture's peak over the resistance just past it, and the growth with depth.
Json needle_json(const NeedleSummary& s) {
  const auto ratio = [](double a, double b) { return b > 0 ? a / b : 0.0; };
  return {{"puncture_peak_N", s.puncture_peak},
          {"insert_early_mean_N", s.insert_early_mean},
          {"insert_late_mean_N", s.insert_late_mean},
          {"peak_over_early", ratio(s.puncture_peak, s.insert_early_mean)},
          {"late_over_early", ratio(s.insert_late_mean, s.insert_early_mean)},
          {"retract_max_N", s.retract_max},
          {"retract_cutting_max_N", s.retract_cutting_max},
          {"lateral_max_N", s.lateral_max},
          {"max_depth_m", s.max_depth},
          {"force_balance_max_N", s.balance_max},
          {"stick_to_slip", s.stick_to_slip},
          {"slip_to_stick", s.slip_to_stick},
          {"axial_displacement_peak_mm", 1e3 * s.axial_displacement_peak},
          {"steps", {{"puncture", s.puncture_steps}, {"insert", s.insert_steps}, {"retract", s.retract_steps}}}};
}

// metrics.json `cut`: the events, and what the CCD and the topology cost on the steps the
// blade was tested.
Json cut_json(const CutTotals& totals, const std::vector<StepStats>& stats) {
  std::vector<double> ccd, topology;
  for (const auto& st : stats)
    if (st.cut_tested) ccd.push_back(st.ms_ccd), topology.push_back(st.ms_topology);
  const auto max_of = [](const std::vector<double>& v) { return v.empty() ? 0.0 : *std::max_element(v.begin(), v.end()); };
  return {{"events", totals.events},
          {"steps_tested", ccd.size()},
          {"links_severed", totals.links_severed},
          {"links_severed_at_rest", totals.links_severed_at_rest},
          {"elements_reselected", totals.elements_reselected},
          {"isolated_elements", totals.isolated_elements},
          {"nonlocal_reselections", totals.nonlocal_reselections},
          {"reselection_failures", totals.reselection_failures},
          {"orphaned_particles", totals.orphaned_particles},
          {"positive_mass_elements", totals.positive_mass_elements},
          {"deactivated_elements", totals.deactivated_elements},
          {"masses_floored", totals.masses_floored},
          {"elements_linked_across", totals.elements_linked_across},
          {"ms_ccd", {{"median", percentile(ccd, 0.5)}, {"max", max_of(ccd)}}},
          {"ms_topology", {{"median", percentile(topology, 0.5)}, {"max", max_of(topology)}}}};
}

// metrics.json `surface`: the surface after the last event, and the worst over every event.
Json surface_json(const World& world, const CutTotals& totals) {
  long vertices = 0, triangles = 0;
  int boundary = 0, nonmanifold = 0;
  for (const auto& body : world.bodies()) {
    vertices += static_cast<long>(body.data.surface_positions.size() / 3);
    triangles += static_cast<long>(body.data.surface.size());
    const physics::SurfaceTopology topology_now = physics::surface_topology(body.data.surface);
    boundary += topology_now.boundary_edges;
    nonmanifold += topology_now.nonmanifold_edges;
  }
  return {{"vertices", vertices},
          {"triangles", triangles},
          {"boundary_edges", boundary},
          {"nonmanifold_edges", nonmanifold},
          {"watertight", boundary == 0 && nonmanifold == 0},
          {"worst_boundary_edges", totals.worst_boundary_edges},
          {"worst_nonmanifold_edges", totals.worst_nonmanifold_edges},
          {"watertight_after_every_event", totals.worst_boundary_edges == 0 && totals.worst_nonmanifold_edges == 0},
          {"front_problems", totals.front_problems},
          {"first_front_problem", totals.first_front_problem},
          {"front_folded_edges", totals.front_folded_edges},
          {"front_strokes_carried_through", totals.front_strokes_carried_through}};
}

// metrics.json `mapping`: how the surface vertices were carried to the cut volume.
Json mapping_json(const World& world, const CutTotals& totals) {
  long unseen = 0;  // at the build: vertices on a point they do not see through the body
  for (const auto& body : world.bodies())
    if (body.cut) unseen += body.cut->mapping.unseen_at_build;
  return {{"vertices_remapped", totals.vertices_remapped},
          {"relaxed_fallbacks", totals.relaxed_fallbacks},
          {"wrong_side", totals.wrong_side},
          {"unseen_at_build", unseen}};
}

// metrics.json `expect`: the scene's expectations, against every metric already there.
Json expect_json(const Scene& scene, const Json& metrics) {
  Json expect = Json::array();
  for (const auto& r : check_expectations(scene, metrics)) {
    Json item = {{"metric", r.metric}, {"passed", r.passed}};
    item["value"] = r.value ? Json(*r.value) : Json(nullptr);
    if (r.min) item["min"] = *r.min;
    if (r.max) item["max"] = *r.max;
    expect.push_back(item);
  }
  return expect;
}

// rest_top.csv: the organ at rest seen from above for the report (its surface's vertices
// before the first step, x and y, one per 0.5 mm cell so a fine surface stays a small file).
void write_rest_top_csv(const std::filesystem::path& file, const World& world) {
  common::CsvWriter csv(file, {"x", "y"});
  std::set<std::pair<long, long>> cells;
  auto add = [&](double x, double y) {
    if (cells.insert({std::lround(x / 5e-4), std::lround(y / 5e-4)}).second) csv.row(x, y);
  };
  for (const auto& body : world.bodies()) {
    if (body.data.embedding) {
      const auto& p = body.data.surface_positions;
      for (Eigen::Index i = 0; i + 2 < p.size(); i += 3) add(p[i], p[i + 1]);
    } else {
      const auto& rest = body.data.mechanics->rest_positions();
      for (int n : body.model->surface_nodes) add(rest[3 * n], rest[3 * n + 1]);
    }
  }
}

void write_metrics_json(const std::filesystem::path& file, const Json& metrics) {
  std::ofstream out(file);
  out << metrics.dump(2) << "\n";
  if (!out) throw std::runtime_error(file.string() + ": cannot write");
}

}  // namespace

// steps.csv, one row per step for plots and review: where time went and what the tool felt.
void write_steps_csv(const std::filesystem::path& file, const std::vector<StepStats>& stats, double dt) {
  common::CsvWriter steps_csv(
      file,
      {"step", "time_s", "ms_total", "ms_tool_input", "ms_contact", "ms_solve", "ms_surface", "cg_iterations",
       "cg_residual", "contacts", "tool_force_x", "tool_force_y", "tool_force_z", "elastic_energy_J",
       "kinetic_energy_J", "ms_ccd", "ms_topology", "links_severed", "ms_rest_cut", "ms_reselect",
       "ms_surface_rebuild", "ms_mapping", "ms_checks", "ms_front_cut", "ms_front_wait", "preconditioner",
       "ms_per_iteration", "preconditioner_age", "preconditioner_build_ms", "preconditioner_wait_ms", "cg_budget_stops",
       "tool_x", "tool_y", "tool_z", "blade_engaged", "cut_event"});
  for (std::size_t k = 0; k < stats.size(); ++k) {
    const auto& s = stats[k];
    steps_csv.row(k + 1, static_cast<double>(k + 1) * dt, s.ms_total, s.ms_tool_input, s.ms_contact,
                  s.ms_solve, s.ms_surface, s.cg_iterations, s.cg_residual, s.contacts, s.tool_force[0],
                  s.tool_force[1], s.tool_force[2], s.elastic_energy, s.kinetic_energy, s.ms_ccd, s.ms_topology,
                  s.links_severed, s.ms_rest_cut, s.ms_reselect, s.ms_surface_rebuild, s.ms_mapping, s.ms_checks,
                  s.ms_front_cut, s.ms_front_wait, s.preconditioner,
                  s.cg_iterations > 0 ? s.ms_solve / s.cg_iterations : 0.0, s.preconditioner_age,
                  s.preconditioner_build_ms, s.preconditioner_wait_ms, s.cg_budget_stops, s.tool_tip[0], s.tool_tip[1],
                  s.tool_tip[2], s.blade_engaged ? 1 : 0, s.cut_event ? 1 : 0);
  }
}

ReplayResult run_replay(const Scene& scene, const ReplayOptions& options) {
  Json trajectory_json;
  std::optional<Trajectory> trajectory = load_trajectory(scene, options, trajectory_json);
  World world(scene, std::move(trajectory));
  const long dofs_initial = count_dofs(world);  // before any step: cutting must never change it
  const RunPlan plan = plan_run(scene, options);

  std::filesystem::create_directories(options.out_dir);
  std::unique_ptr<Capture> capture = start_capture(plan);
  write_rest_top_csv(options.out_dir / "rest_top.csv", world);
  RunOutcome run = run_steps(world, scene, options, plan, capture.get());

  Json metrics = run_metrics(scene, world, run, plan, dofs_initial, trajectory_json);
  if (scene.solver.backend == "gpu") metrics["gpu"] = gpu_json(world, run.stats);
  if (capture) add_frames_metrics(metrics, *capture, plan, run.error);
  ReplayResult result;
  if (!run.error.empty()) {
    metrics["error"] = run.error;
    result.ok = false;
  }
  if (any_cuttable(world)) {
    const CutTotals& totals = world.cut_totals();
    metrics["cut"] = cut_json(totals, run.stats);
    metrics["surface"] = surface_json(world, totals);
    metrics["mapping"] = mapping_json(world, totals);
  }
  if (world.needle()) {
    metrics["needle"] = needle_json(summarise_needle(run.stats));
    // A template of several needles: the block above sums their forces; each its own here.
    if (world.needle_count() > 1) {
      Json each = Json::array();
      for (std::size_t k = 0; k < world.needle_count(); ++k) {
        Json one = needle_json(summarise_needle(run.stats, k));
        one.erase("axial_displacement_peak_mm");
        each.push_back(std::move(one));
      }
      metrics["needle"]["needles"] = std::move(each);
    }
  }
  if (scene.plan) {
    try {
      const IncisionScore score = score_incision(*scene.plan, world, run.stats, scene.solver.dt);
      metrics["score"] = score_json(score);
      write_score_files(options.out_dir, *scene.plan, score);
    } catch (const std::exception& e) {
      metrics["score_error"] = e.what();
      result.ok = false;
    }
  }
  // After every other metric: an expectation may name any of them (the cut's and the score's too).
  if (!scene.expect.empty()) metrics["expect"] = expect_json(scene, metrics);
  write_steps_csv(options.out_dir / "steps.csv", run.stats, scene.solver.dt);
  write_metrics_json(options.out_dir / "metrics.json", metrics);
  result.metrics = std::move(metrics);
  return result;
}

}  // namespace incise::engine
