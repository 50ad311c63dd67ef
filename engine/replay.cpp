#include "engine/replay.hpp"

#include "common/csv.hpp"
#include "common/percentile.hpp"
#include "common/progress_bar.hpp"
#include "engine/publication.hpp"
#include "engine/trajectory.hpp"
#include "engine/world.hpp"
#include "physics/gpu/efg_step.hpp"
#include "render/image.hpp"
#include "render/offscreen.hpp"

#include <algorithm>
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

}  // namespace

ReplayResult run_replay(const Scene& scene, const ReplayOptions& options) {
  std::optional<Trajectory> trajectory;
  std::optional<std::filesystem::path> trajectory_file = options.trajectory;
  if (!trajectory_file && scene.tool) trajectory_file = scene.tool->trajectory;
  if (trajectory_file) trajectory = read_trajectory(*trajectory_file);
  Json trajectory_json = nullptr;
  if (trajectory) {
    trajectory_json = {{"file", trajectory_file->string()},
                       {"samples", trajectory->samples.size()},
                       {"chunks", trajectory->report.chunks_read},
                       {"complete", trajectory->report.complete},
                       {"problem", trajectory->report.problem}};
  }

  World world(scene, std::move(trajectory));
  long dofs_initial = 0;  // counted before any step: cutting must never change it
  for (const auto& body : world.bodies()) dofs_initial += 3L * body.data.mechanics->node_count();
  const long steps = options.steps ? *options.steps
                                   : std::lround(scene.solver.duration / scene.solver.dt);
  const int capture_every = options.capture_every ? *options.capture_every : scene.render.capture_every;
  const int width = options.size ? options.size->first : scene.render.width;
  const int height = options.size ? options.size->second : scene.render.height;

  std::filesystem::create_directories(options.out_dir);
  const auto frames_dir = options.out_dir / "frames";
  std::unique_ptr<Capture> capture;
  if (capture_every > 0) {
    std::filesystem::create_directories(frames_dir);
    for (const auto& entry : std::filesystem::directory_iterator(frames_dir))
      if (entry.path().extension() == ".png") std::filesystem::remove(entry.path());
    capture = std::make_unique<Capture>(frames_dir, width, height);
  }

  std::vector<StepStats> stats;
  stats.reserve(static_cast<std::size_t>(std::max(0L, steps)));
  std::atomic<long> steps_done{0};
  std::string error;
  auto publish = [&](std::uint64_t step) {
    if (!capture) return;
    if (Snapshot* s = capture->begin()) {
      s->step = step;
      s->time = world.time();
      world.fill_frame(s->frame, width, height);
      capture->end();
    }
  };

  const auto wall_start = Clock::now();
  std::thread physics([&] {
    try {
      publish(0);
      for (long k = 1; k <= steps; ++k) {
        stats.push_back(world.step());
        if (capture_every > 0 && k % capture_every == 0) publish(static_cast<std::uint64_t>(k));
        steps_done.store(k, std::memory_order_release);
      }
    } catch (const std::exception& e) {
      error = e.what();
    }
    steps_done.store(-1, std::memory_order_release);
  });
  const bool tty = options.progress && isatty(STDERR_FILENO);
  common::ProgressBar bar(std::cerr, steps);
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
  const double wall = std::chrono::duration<double>(Clock::now() - wall_start).count();
  if (tty) {
    bar.set_done(static_cast<long>(stats.size()));
    bar.draw(progress_text(world.time(), wall));
    bar.finish();
  }

  // Metrics.
  std::vector<double> total, tool_input, cut_phase, contact, solve, surface;
  double cg_sum = 0, cg_residual_max = 0, max_force = 0;
  int cg_max = 0, nonfinite = 0, not_converged = 0, contacts_max = 0;
  for (const auto& s : stats) {
    total.push_back(s.ms_total);
    tool_input.push_back(s.ms_tool_input);
    cut_phase.push_back(s.ms_ccd + s.ms_topology);
    contact.push_back(s.ms_contact);
    solve.push_back(s.ms_solve);
    surface.push_back(s.ms_surface);
    cg_sum += s.cg_iterations;
    cg_max = std::max(cg_max, s.cg_iterations);
    cg_residual_max = std::max(cg_residual_max, s.cg_residual);
    nonfinite += s.nonfinite_events;
    not_converged += s.cg_converged ? 0 : 1;
    contacts_max = std::max(contacts_max, s.contacts);
    max_force = std::max(max_force, std::sqrt(s.tool_force[0] * s.tool_force[0] +
                                              s.tool_force[1] * s.tool_force[1] +
                                              s.tool_force[2] * s.tool_force[2]));
  }
  std::array<double, 3> centroid{};
  double mean_displacement = 0, max_displacement = 0;
  std::size_t nodes = 0;
  Json bodies = Json::array();
  for (const auto& body : world.bodies()) {
    const auto& x = body.data.state.positions;
    const auto& rest = body.data.mechanics->rest_positions();
    const int n = body.data.mechanics->node_count();
    for (int i = 0; i < n; ++i) {
      for (int c = 0; c < 3; ++c) centroid[c] += x[3 * i + c];
      double d = (x.segment<3>(3 * i) - rest.segment<3>(3 * i)).norm();
      mean_displacement += d;
      max_displacement = std::max(max_displacement, d);
    }
    nodes += static_cast<std::size_t>(n);
    int fixed = 0;
    for (auto f : body.data.fixed) fixed += f;
    // What the user sees moved: the surface vertices (nodes of a tetrahedral body; embedded
    // vertices of a meshless one, whose particles may lie outside the body).
    double surface_max = 0;
    std::size_t surface_vertices = 0;
    if (body.data.embedding) {
      physics::Vector rest_vertices;
      physics::CorotationalEfg::surface_positions(*body.data.embedding, rest, rest_vertices);
      const auto indices = static_cast<std::size_t>(body.data.embedding->vertex_count());
      surface_vertices = indices;
      for (std::size_t v = 0; v < indices; ++v) {
        const auto at = static_cast<Eigen::Index>(3 * v);
        surface_max = std::max(surface_max, (body.data.surface_positions.segment<3>(at) - rest_vertices.segment<3>(at)).norm());
      }
    } else {
      surface_vertices = body.model->surface_nodes.size();
      for (int node : body.model->surface_nodes)
        surface_max = std::max(surface_max, (x.segment<3>(3 * node) - rest.segment<3>(3 * node)).norm());
    }
    bodies.push_back({{"name", body.model->name},
                      {"model", body.data.embedding ? "efg_corotated" : "fem_corotational_tet4"},
                      {"surface_vertices", surface_vertices},
                      {"surface_max_displacement", surface_max},
                      {"nodes", n},
                      {"dofs", 3 * n},
                      {"elements", body.model->elements},
                      {"fixed_nodes", fixed},
                      {"surface_triangles", body.data.surface.size()}});
  }
  for (auto& c : centroid) c /= static_cast<double>(std::max<std::size_t>(nodes, 1));
  mean_displacement /= static_cast<double>(std::max<std::size_t>(nodes, 1));
  const StepStats last = stats.empty() ? StepStats{} : stats.back();
  long dofs_final = 0;
  for (const auto& body : world.bodies()) dofs_final += 3L * body.data.mechanics->node_count();

  Json metrics = {
      {"scene", scene.name},
      {"scene_file", scene.file.string()},
      {"backend", backend_json(world)},
      {"steps", stats.size()},
      {"steps_requested", steps},
      {"dt_s", scene.solver.dt},
      {"sim_time_s", world.time()},
      {"wall_time_s", wall},
      {"ms_per_step", {{"median", percentile(total, 0.5)}, {"p95", percentile(total, 0.95)},
                       {"max", total.empty() ? 0 : *std::max_element(total.begin(), total.end())}}},
      {"phases_ms", {{"tool_input", percentile(tool_input, 0.5)}, {"cut", percentile(cut_phase, 0.5)}, {"contact", percentile(contact, 0.5)},
                     {"solve", percentile(solve, 0.5)}, {"surface", percentile(surface, 0.5)}}},
      {"cg_iterations", {{"mean", stats.empty() ? 0.0 : cg_sum / static_cast<double>(stats.size())},
                         {"max", cg_max}}},
      {"cg_residual_max", cg_residual_max},
      {"cg_not_converged_steps", not_converged},
      {"nonfinite_events", nonfinite},
      {"guards", guards_json(world)},
      {"energy_J", {{"elastic", last.elastic_energy}, {"kinetic", last.kinetic_energy}}},
      {"positions_digest", {{"centroid", centroid},
                            {"mean_displacement", mean_displacement},
                            {"max_displacement", max_displacement}}},
      {"state_hash", hex64(world.state_hash())},
      {"motion_hash", hex64(world.motion_hash())},
      {"bodies", bodies},
      {"tool", {{"max_force_N", max_force}, {"max_contacts", contacts_max}}},
      {"dofs", {{"initial", dofs_initial}, {"final", dofs_final}}},
      {"trajectory", trajectory_json},
  };
  if (scene.solver.backend == "gpu") metrics["gpu"] = gpu_json(world, stats);
  if (capture) {
    metrics["frames"] = {{"count", capture->frames()},
                         {"every_steps", capture_every},
                         {"dir", frames_dir.string()},
                         {"size", {width, height}},
                         {"renderer", capture->renderer()},
                         {"ms_render_median", capture->ms_render_median()}};
    if (capture->failed()) {
      metrics["frames"]["error"] = capture->error();
      if (error.empty()) error = "off-screen capture failed: " + capture->error();
    }
  }
  ReplayResult result;
  if (!error.empty()) {
    metrics["error"] = error;
    result.ok = false;
  }
  bool cuttable = false;
  for (const auto& body : world.bodies()) cuttable = cuttable || body.cut != nullptr;
  if (cuttable) {
    // Cutting: events, what the CCD and the topology cost on the steps the blade was tested,
    // the surface after the last event (and the worst over every event), the mapping.
    std::vector<double> ccd, topology;
    for (const auto& st : stats)
      if (st.cut_tested) ccd.push_back(st.ms_ccd), topology.push_back(st.ms_topology);
    const auto max_of = [](const std::vector<double>& v) { return v.empty() ? 0.0 : *std::max_element(v.begin(), v.end()); };
    const CutTotals& totals = world.cut_totals();
    metrics["cut"] = {{"events", totals.events},
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
    long vertices = 0, triangles = 0;
    int boundary = 0, nonmanifold = 0;
    for (const auto& body : world.bodies()) {
      vertices += static_cast<long>(body.data.surface_positions.size() / 3);
      triangles += static_cast<long>(body.data.surface.size());
      const physics::SurfaceTopology topology_now = physics::surface_topology(body.data.surface);
      boundary += topology_now.boundary_edges;
      nonmanifold += topology_now.nonmanifold_edges;
    }
    metrics["surface"] = {{"vertices", vertices},
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
    metrics["mapping"] = {{"vertices_remapped", totals.vertices_remapped},
                          {"relaxed_fallbacks", totals.relaxed_fallbacks},
                          {"wrong_side", totals.wrong_side}};
  }
  // The scene's expectations, against every metric above (the cut's too).
  if (!scene.expect.empty()) {
    Json expect = Json::array();
    for (const auto& r : check_expectations(scene, metrics)) {
      Json item = {{"metric", r.metric}, {"passed", r.passed}};
      item["value"] = r.value ? Json(*r.value) : Json(nullptr);
      if (r.min) item["min"] = *r.min;
      if (r.max) item["max"] = *r.max;
      expect.push_back(item);
    }
    metrics["expect"] = expect;
  }
  {
    // One row per step for plots and review: where time went and what the tool felt.
    common::CsvWriter steps_csv(
        options.out_dir / "steps.csv",
        {"step", "time_s", "ms_total", "ms_tool_input", "ms_contact", "ms_solve", "ms_surface", "cg_iterations",
         "cg_residual", "contacts", "tool_force_x", "tool_force_y", "tool_force_z", "elastic_energy_J",
         "kinetic_energy_J", "ms_ccd", "ms_topology", "links_severed", "ms_rest_cut", "ms_reselect",
         "ms_surface_rebuild", "ms_mapping", "ms_checks", "ms_front_cut", "ms_front_wait"});
    for (std::size_t k = 0; k < stats.size(); ++k) {
      const auto& s = stats[k];
      steps_csv.row(k + 1, static_cast<double>(k + 1) * scene.solver.dt, s.ms_total, s.ms_tool_input, s.ms_contact,
                    s.ms_solve, s.ms_surface, s.cg_iterations, s.cg_residual, s.contacts, s.tool_force[0],
                    s.tool_force[1], s.tool_force[2], s.elastic_energy, s.kinetic_energy, s.ms_ccd, s.ms_topology,
                    s.links_severed, s.ms_rest_cut, s.ms_reselect, s.ms_surface_rebuild, s.ms_mapping, s.ms_checks,
                    s.ms_front_cut, s.ms_front_wait);
    }
  }
  std::ofstream out(options.out_dir / "metrics.json");
  out << metrics.dump(2) << "\n";
  if (!out) throw std::runtime_error((options.out_dir / "metrics.json").string() + ": cannot write");
  result.metrics = std::move(metrics);
  return result;
}

}  // namespace incise::engine
