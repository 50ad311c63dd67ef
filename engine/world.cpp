#include "engine/world.hpp"

#include "engine/body_builder.hpp"
#include "engine/model_registry.hpp"
#include "physics/cut/apply_topology.hpp"
#include "physics/cut/detect_cuts.hpp"
#include "physics/gpu/efg_step.hpp"

#include "physics/core/stopwatch.hpp"

#include <algorithm>
#include <cmath>

namespace incise::engine {

World::World(const Scene& scene, std::optional<Trajectory> trajectory)
    : scene_(scene), trajectory_(std::move(trajectory)), initial_trajectory_(trajectory_),
      budget_(scene_.solver.realtime_min_iterations) {
  if (trajectory_) budget_.repeat(trajectory_->cg_stops);
  build();
}

void World::build() {
  bounds_min_ = {1e300, 1e300, 1e300};
  bounds_max_ = {-1e300, -1e300, -1e300};
  for (const auto& spec : scene_.bodies) {
    // A body's refusal (its mesh, its size, its fixed boxes) names the scene file it is in.
    try {
      bodies_.push_back(build_body(spec, scene_.solver));
    } catch (const std::runtime_error& e) {
      throw std::runtime_error(scene_.file.string() + ": bodies[" + std::to_string(bodies_.size()) + "]: " + e.what());
    }
    if (scene_.solver.backend == "gpu") make_gpu_backend(bodies_.back(), bodies_.size() - 1);
    // Particles of a meshless body can lie outside it: frame what is seen.
    const Body& built = bodies_.back();
    const auto& x = built.data.embedding ? built.data.surface_positions : built.data.state.positions;
    for (Eigen::Index i = 0; i < x.size(); ++i) {
      bounds_min_[i % 3] = std::min(bounds_min_[i % 3], x[i]);
      bounds_max_[i % 3] = std::max(bounds_max_[i % 3], x[i]);
    }
  }
  for (std::size_t l = 0; l < scene_.loads.size(); ++l) {
    const auto& load = scene_.loads[l];
    for (auto& body : bodies_) {
      if (body.model->name != load.body) continue;
      auto model = std::make_shared<physics::BodyModel>(*body.model);
      std::vector<int> nodes;
      const auto& x = body.data.state.positions;
      for (int i = 0; i < body.data.mechanics->node_count(); ++i)
        if (load.region.contains({x[3 * i], x[3 * i + 1], x[3 * i + 2]}, 1e-9)) nodes.push_back(i);
      if (nodes.empty())
        throw std::runtime_error(scene_.file.string() + ": loads[" + std::to_string(l) +
                                 "].region: contains no node of body '" + body.model->name + "'");
      model->load_nodes.push_back(std::move(nodes));
      model->load_index.push_back(l);
      body.model = std::move(model);
    }
  }
  if (scene_.tool) {
    if (!trajectory_)
      throw std::runtime_error(scene_.file.string() + ": tool.trajectory: none given (set it in the scene or pass "
                               "--trajectory FILE; `incise run` and `incise session` drive the tool live)");
    if (trajectory_->samples.empty())
      throw std::runtime_error(scene_.file.string() + ": tool.trajectory: holds no sample");
    tool_.present = true;
    tool_.radius = scene_.tool->radius;
  }
  take_tool_input(0.0);
  build_needle();
}

void World::reset() {
  bodies_.clear();
  trajectory_ = initial_trajectory_;
  tool_ = ToolState{};
  time_ = 0;
  steps_ = 0;
  guard_counts_ = GuardCounts{};
  cut_totals_ = CutTotals{};
  guard_events_.clear();
  budget_.reset();
  ms_after_solve_ = 0;
  build();
}

void World::make_gpu_backend(Body& body, std::size_t index) const {
  const std::string where = scene_.file.string() + ": solver.backend: 'gpu': ";
  const ModelEntry* model = models().find(body.model->kind);
  if (!model || !model->gpu)
    throw std::runtime_error(where + "bodies[" + std::to_string(index) + "] ('" + body.model->name + "') has model '" +
                             body.model->kind + "'; the GPU backend runs " +
                             alternatives(models().names_where(&ModelEntry::gpu), false) + " bodies only");
  // The GPU step is the EFG model's (physics/gpu/efg_step.hpp): a model registered with `gpu`
  // builds its bodies' mechanics as a CorotationalEfg.
  if (!body.data.efg)
    throw std::runtime_error(where + "model '" + body.model->kind + "' is registered as running on the GPU but its "
                           "builder made no CorotationalEfg for the GPU step");
  physics::gpu::GpuSettings settings;
  settings.precision = scene_.solver.precision == "double" ? physics::gpu::Precision::double_precision
                                                           : physics::gpu::Precision::single;
  settings.batch_rows = scene_.solver.batch_rows;
  try {
    body.gpu = std::make_shared<physics::gpu::EfgStep>(*body.data.efg, settings);
    if (body.data.embedding) body.gpu->upload_surface(*body.data.embedding);
  } catch (const std::exception& e) {
    throw std::runtime_error(where + e.what());
  }
}

void World::log_guard(const std::string& body, const std::string& kind, const std::string& detail) {
  if (guard_events_.size() >= kGuardLogLimit) return;
  guard_events_.push_back({steps_ + 1, static_cast<double>(steps_ + 1) * scene_.solver.dt, body, kind, detail});
}


physics::BladeSweep World::blade_sweep() const {
  // The onset's step: the stroke starts where the edge met the tissue (BladeSweep::entry).
  const bool onset_step = tool_.cutting.cutting && !tool_.cutting.entry.empty();
  return {tool_.blade_poses, tool_.blade_fractions, tool_.blade_active, onset_step ? &tool_.cutting.entry : nullptr};
}

std::optional<physics::RestSweep> World::detect_cuts(Body& body, physics::CutStepReport& report) {
  return physics::detect_cuts(*body.cut_model, *body.cut, body.data, blade_sweep(), report);
}

void World::apply_topology(Body& body, const std::optional<physics::RestSweep>& sweep, physics::CutStepReport& report) {
  physics::CutContext context{*body.model, body.data, *body.cut_model, *body.cut, cut_totals_, report,
                              body.gpu != nullptr, static_cast<long>(steps_ + 1)};
  physics::apply_topology(context, blade_sweep(), sweep, body.threads());
}

namespace {

void add_cut_report(const physics::CutStepReport& report, StepStats& stats) {
  stats.cut_tested = stats.cut_tested || report.tested;
  stats.cut_event = stats.cut_event || report.event;
  stats.ms_ccd += report.ms_ccd;
  stats.ms_topology += report.ms_topology;
  stats.ms_rest_cut += report.ms_rest_cut;
  stats.ms_reselect += report.ms_reselect;
  stats.ms_surface_rebuild += report.ms_surface_rebuild;
  stats.ms_mapping += report.ms_mapping;
  stats.ms_checks += report.ms_checks;
  stats.ms_front_cut += report.ms_front_cut;
  stats.ms_front_wait += report.ms_front_wait;
  stats.links_severed += report.links_severed;
}

}  // namespace

StepStats World::step(std::int64_t deadline_ns) {
  StepStats stats;
  const auto gpu_bytes = [this](bool rows) {
    long long bytes = 0;
    for (const auto& body : bodies_)
      if (body.gpu) bytes += rows ? body.gpu->counters().row_bytes : body.gpu->counters().bytes_uploaded();
    return bytes;
  };
  const long long gpu_bytes_before = gpu_bytes(false), gpu_row_bytes_before = gpu_bytes(true);
  const physics::Stopwatch whole;
  physics::Stopwatch phase;
  const double end_time = static_cast<double>(steps_ + 1) * scene_.solver.dt;
  take_tool_input(end_time);
  stats.ms_tool_input = phase.ms();
  stats.tool_tip = tool_.tip;
  stats.blade_engaged = std::find(tool_.blade_active.begin(), tool_.blade_active.end(), 1) != tool_.blade_active.end();
  phase.restart();
  resist_cutting(stats);
  stats.ms_resistance = phase.ms();
  budget_.begin_step(steps_ + 1, deadline_ns > 0 ? deadline_ns - static_cast<std::int64_t>(ms_after_solve_ * 1e6) : 0);
  for (auto& body : bodies_) {
    if (!body.cut || !blade()) continue;  // a body is cut by a blade only
    physics::CutStepReport cut;
    const auto sweep = detect_cuts(body, cut);
    apply_topology(body, sweep, cut);
    add_cut_report(cut, stats);
    // The edge cut its way out of the body: with the onset, the engagement ends as when it
    // leaves the tissue, so that tissue it meets again (a freed piece swinging back onto it)
    // is pressed first and cut from where the edge met it (CuttingState::entry), not from a
    // new stroke's first sample inside it.
    if (cut.cut_through && scene_.tool->onset && tool_.cutting.cutting) tool_.leaving = true;
  }
  if (tool_.cutting.cutting) tool_.cutting.entry.clear();  // the stroke has its first sample
  if (tool_.leaving) tool_.cutting = {};                    // the edge is out: the next entry presses
  std::vector<std::vector<physics::NodalSpring>> springs(bodies_.size());
  phase.restart();
  for (std::size_t b = 0; b < bodies_.size(); ++b) springs[b] = contact(bodies_[b], stats);
  if (needle()) {
    auto pushed = insert_needle(stats);
    for (std::size_t b = 0; b < bodies_.size(); ++b) springs[b].insert(springs[b].end(), pushed[b].begin(), pushed[b].end());
  }
  stats.ms_contact = phase.ms();
  phase.restart();
  const std::vector<physics::Vec3> centres = tool_.pressing ? mass_centres() : std::vector<physics::Vec3>{};
  for (std::size_t b = 0; b < bodies_.size(); ++b) solve(bodies_[b], springs[b], end_time, stats);
  if (tool_.pressing) advance_onset(centres, stats);
  stats.ms_solve = phase.ms();
  phase.restart();
  for (auto& body : bodies_) update_surface(body);
  stats.ms_surface = phase.ms();
  ms_after_solve_ = stats.ms_surface;
  ++steps_;
  time_ = end_time;
  stats.ms_total = whole.ms();
  stats.gpu_bytes = gpu_bytes(false) - gpu_bytes_before;
  stats.gpu_row_bytes = gpu_bytes(true) - gpu_row_bytes_before;
  return stats;
}

namespace {

// FNV-1a, continued over the bytes of `data`.
void fnv1a(std::uint64_t& hash, const void* data, std::size_t bytes) {
  const auto* p = static_cast<const unsigned char*>(data);
  for (std::size_t i = 0; i < bytes; ++i) {
    hash ^= p[i];
    hash *= 1099511628211ull;
  }
}

template <typename T>
void fnv1a(std::uint64_t& hash, const std::vector<T>& v) {
  fnv1a(hash, v.data(), v.size() * sizeof(T));
}

void fnv1a(std::uint64_t& hash, const physics::Vector& v) {
  fnv1a(hash, v.data(), static_cast<std::size_t>(v.size()) * sizeof(double));
}

constexpr std::uint64_t fnv_offset = 1469598103934665603ull;

}  // namespace

std::uint64_t World::motion_hash() const {
  std::uint64_t hash = fnv_offset;
  for (const auto& body : bodies_) {
    fnv1a(hash, body.data.state.positions);
    fnv1a(hash, body.data.state.velocities);
    for (const physics::Vector& solution : body.data.warm_start.solutions()) fnv1a(hash, solution);
  }
  return hash;
}

std::uint64_t World::state_hash() const {
  std::uint64_t hash = motion_hash();
  for (const auto& body : bodies_) {
    // What a cut changes besides the motion: the fixed particles, the masses, the EFG rows
    // (neighbourhoods and shape functions), the surface and its mapping.
    fnv1a(hash, body.data.fixed);
    fnv1a(hash, body.data.mechanics->lumped_masses());
    if (const physics::CorotationalEfg* efg = body.data.efg) {
      fnv1a(hash, efg->row_lengths());
      fnv1a(hash, efg->neighbours());
      fnv1a(hash, efg->shape_values());
      fnv1a(hash, efg->element_volumes());
    }
    fnv1a(hash, body.data.surface);
    if (body.data.embedding) {
      fnv1a(hash, body.data.embedding->elements);
      fnv1a(hash, body.data.embedding->row_lengths);
      fnv1a(hash, body.data.embedding->particles);
      fnv1a(hash, body.data.embedding->weights);
    }
    if (body.cut) fnv1a(hash, body.cut->surface->vertices());
  }
  if (blade() && scene_.tool->onset) {
    // The crack's onset decides whether the next steps cut.
    const std::uint8_t cutting = tool_.cutting.cutting ? 1 : 0;
    fnv1a(hash, &cutting, 1);
    fnv1a(hash, &tool_.cutting.work, sizeof(double));
    for (const auto& point : tool_.cutting.entry) fnv1a(hash, point.data(), 3 * sizeof(double));
  }
  if (needle()) {
    // The needle's zones and its virtual particles decide the next steps' forces.
    for (const NeedleTrack& track : needle_) {
      fnv1a(hash, track.last_tip.data(), 3 * sizeof(double));
      for (const physics::Needle& n : track.bodies) {
        fnv1a(hash, n.grips());
        for (const auto& m : n.zones().cutting) fnv1a(hash, &m.atom, sizeof(int));
        for (const auto& zone : n.zones().friction)
          for (const auto& m : zone) fnv1a(hash, &m.atom, sizeof(int));
        for (const auto& p : n.particles()) {
          fnv1a(hash, p.atoms);
          fnv1a(hash, p.weights);
          fnv1a(hash, p.offset.data(), 3 * sizeof(double));
        }
      }
    }
  }
  return hash;
}

}  // namespace incise::engine
