#include "app/window_physics.hpp"

#include "haptics/clock.hpp"

#include <cstdio>
#include <exception>

namespace incise::app {

void LiveSnapshot::Totals::add(const engine::StepStats& stats) {
  ms_cut += stats.ms_ccd + stats.ms_topology;
  ms_contact += stats.ms_contact;
  ms_solve += stats.ms_solve;
  ms_surface += stats.ms_surface;
  ms_step += stats.ms_total;
  cg_iterations += stats.cg_iterations;
  over_budget += stats.cg_budget_stops > 0 ? 1 : 0;
  ++steps;
}

namespace {

std::filesystem::path numbered(const std::filesystem::path& base, int k) {
  if (k <= 1) return base;
  return base.parent_path() / (base.stem().string() + "_" + std::to_string(k) + base.extension().string());
}

// The session the window runs, restarted by the panels' requests.
class WindowPhysics {
 public:
  WindowPhysics(const engine::Scene& scene, haptics::Device& device, const WindowPhysicsSettings& settings,
                WindowShared& shared)
      : current_(scene), device_(device), settings_(settings), shared_(shared) {}

  void run() {
    begin(settings_.record_at_start);
    for (const auto& body : session_->world().bodies()) shared_.triangles_at_start += body.data.surface.size();
    publish({}, 0);
    shared_.ready.store(true, std::memory_order_release);
    while (!shared_.stop.load(std::memory_order_acquire)) {
      Request r;
      while (shared_.requests.try_pop(r)) apply(r);
      // step() waits for the haptic tick after the step's end: physics keeps to the hand's
      // time; in real time (solver.realtime) its CG stops when the hand is a step further,
      // otherwise it falls behind when a step takes longer than dt.
      const engine::StepStats stats = session_->step();
      // Against the hand's clock, which starts before the world is built (t0 of the session).
      const double wall = 1e-9 * static_cast<double>(haptics::monotonic_now_ns() - session_->t0_ns());
      publish(stats, wall > 0 ? session_->world().time() / wall : 0);
    }
    end();
  }

  // After an error: stop the loop quietly, the error is what gets reported.
  void abandon() noexcept {
    shared_.loop_view.store(nullptr, std::memory_order_release);
    if (!session_) return;
    try {
      session_->stop();
    } catch (const std::exception&) {
    }
  }

 private:
  // Stops the running session (its recording's summary written) and starts a new one.
  void begin(bool record) {
    if (session_) end();
    engine::SessionOptions o = settings_.options;
    recording_ = record;
    if (record) {
      record_file_ = numbered(settings_.record_base, ++recordings_);
      o.record = record_file_;
      shared_.last_recording = record_file_.string();
    }
    session_ = std::make_unique<engine::HapticSession>(current_, device_, o);
    shared_.loop_view.store(&session_->loop(), std::memory_order_release);
    ++session_count_;
    if (settings_.udp) {
      const auto port = static_cast<unsigned>(settings_.udp->bound_port());
      std::printf("udp device: listening on %s:%u (e.g. incise-bridge --device %s:%u)\n", settings_.udp_bind.c_str(), port,
                  settings_.udp_bind.c_str(), port);
      std::fflush(stdout);
    }
  }

  void end() {
    shared_.loop_view.store(nullptr, std::memory_order_release);
    session_->stop();
    if (recording_) engine::write_session_summary(*session_, record_file_.string() + ".json");
    session_.reset();
  }

  void apply(const Request& r) {
    if (r.kind != Request::Kind::apply_parameters) {
      begin(r.kind == Request::Kind::record_start);
      return;
    }
    for (auto& body : current_.bodies) {
      body.material.youngs_modulus = r.youngs_modulus;
      body.material.poisson_ratio = r.poisson_ratio;
    }
    current_.solver.tolerance = r.tolerance;
    current_.solver.max_iterations = r.max_iterations;
    begin(false);
  }

  void publish(const engine::StepStats& stats, double real_time_factor) {
    const engine::World& world = session_->world();
    LiveSnapshot& s = shared_.latest.back();
    world.fill_frame(s.frame, settings_.width, settings_.height);
    s.stats = stats;
    s.time = world.time();
    s.step = world.steps_taken();
    s.real_time_factor = real_time_factor;
    s.cut_events = world.cut_totals().events;
    s.triangles = 0;
    for (const auto& body : world.bodies()) s.triangles += body.data.surface.size();
    s.recording = recording_;
    s.recording_file = recording_ ? record_file_.string() : std::string();
    if (totals_session_ != session_count_) totals_ = {}, totals_session_ = session_count_;
    if (stats.ms_total > 0) totals_.add(stats);
    s.session = session_count_;
    s.totals = totals_;
    shared_.latest.publish();
  }

  engine::Scene current_;  // the scene with the panel's parameters applied
  haptics::Device& device_;
  const WindowPhysicsSettings& settings_;
  WindowShared& shared_;
  std::unique_ptr<engine::HapticSession> session_;
  int session_count_ = 0, recordings_ = 0, totals_session_ = -1;
  bool recording_ = false;
  std::filesystem::path record_file_;
  LiveSnapshot::Totals totals_;
};

}  // namespace

void run_window_physics(const engine::Scene& scene, haptics::Device& device, const WindowPhysicsSettings& settings,
                        WindowShared& shared) {
  WindowPhysics physics(scene, device, settings, shared);
  try {
    physics.run();
  } catch (const std::exception& e) {
    shared.physics_error = e.what();
    physics.abandon();
  }
  shared.stop.store(true, std::memory_order_release);
}

}  // namespace incise::app
