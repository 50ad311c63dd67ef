// `incise run`: the interactive window. GLFW wants the main thread, so the main thread is
// the render thread here. Three threads (DESIGN.md):
//   haptic (1 kHz)  the HapticLoop, reading the device (the mouse through a VirtualDevice, a
//                   replay, or a udp bridge) and rendering forces from the ContactModel;
//   physics         an engine::HapticSession: drains the loop's ticks as the blade's sweep,
//                   steps, publishes the ContactModel and a LiveSnapshot (triple buffer);
//   render (main)   draws the newest snapshot and the ImGui panels, turns the cursor into
//                   the virtual device's pose, and writes requests (parameters, record/stop)
//                   into a single-producer queue the physics thread reads between steps.
// Nothing here touches physics state: a parameter change or a recording restarts the session
// from the scene's initial state on the physics thread, so every recording starts at t = 0
// and replays headless to the same state (its summary FILE.json says how many steps).
#include "app/commands.hpp"

#include "engine/haptic_session.hpp"
#include "engine/publication.hpp"
#include "engine/scene.hpp"
#include "engine/trajectory.hpp"
#include "engine/world.hpp"
#include "haptics/clock.hpp"
#include "haptics/replay_device.hpp"
#include "haptics/spsc_ring.hpp"
#include "haptics/udp_device.hpp"
#include "haptics/virtual_device.hpp"
#include "render/image.hpp"
#include "render/transform.hpp"
#include "render/window.hpp"

#include <imgui.h>
#include <nlohmann/json.hpp>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <thread>

namespace incise::app {

namespace {

using SteadyClock = std::chrono::steady_clock;

struct LiveSnapshot {
  render::Frame frame;
  engine::StepStats stats;
  double time = 0;
  std::uint64_t step = 0;
  double real_time_factor = 0;
  long cut_events = 0;
  std::size_t triangles = 0;
  bool recording = false;
  std::string recording_file;
  int session = 0;  // counts restarts
  // Where physics' time went since the session (re)started: sums over its steps, in ms, of the
  // cut (CCD and topology), contact, solve and surface phases and the whole step; CG
  // iterations; steps whose CG the real-time budget stopped.
  struct Totals {
    double ms_cut = 0, ms_contact = 0, ms_solve = 0, ms_surface = 0, ms_step = 0, cg_iterations = 0;
    std::uint64_t steps = 0, over_budget = 0;
    void add(const engine::StepStats& stats) {
      ms_cut += stats.ms_ccd + stats.ms_topology;
      ms_contact += stats.ms_contact;
      ms_solve += stats.ms_solve;
      ms_surface += stats.ms_surface;
      ms_step += stats.ms_total;
      cg_iterations += stats.cg_iterations;
      over_budget += stats.cg_budget_stops > 0 ? 1 : 0;
      ++steps;
    }
  } totals;
};

// Requests from the panels to the physics thread (plain values: the queue never allocates).
struct Request {
  enum class Kind { apply_parameters, record_start, record_stop } kind = Kind::apply_parameters;
  double youngs_modulus = 0, poisson_ratio = 0, tolerance = 0;
  int max_iterations = 0;
};

// A history for ImGui::PlotLines.
struct Plot {
  static constexpr int kLength = 240;
  std::array<float, kLength> values{};
  int next = 0, count = 0;
  void push(float v) {
    values[next] = v;
    next = (next + 1) % kLength;
    count = std::min(count + 1, kLength);
  }
  void draw(const char* label, const char* unit, float lo, float hi) const {
    char overlay[64];
    const float last = count ? values[(next + kLength - 1) % kLength] : 0.0f;
    std::snprintf(overlay, sizeof overlay, "%.3g %s", last, unit);
    ImGui::PlotLines(label, values.data(), kLength, next, overlay, lo, hi, ImVec2(190, 30));
  }
};

std::array<int, 4> parse_drag(const std::string& text, double& depth) {
  std::array<int, 4> d{};
  depth = 0.008;
  char extra = 0;
  const int n = std::sscanf(text.c_str(), "%d,%d,%d,%d,%lf%c", &d[0], &d[1], &d[2], &d[3], &depth, &extra);
  if (n != 4 && n != 5)
    throw std::runtime_error("--script-drag: '" + text + "' is not x0,y0,x1,y1[,depth_m] (pixels, metres)");
  if (!(depth >= 0 && depth < 0.1)) throw std::runtime_error("--script-drag: depth " + std::to_string(depth) + " m is outside [0, 0.1)");
  return d;
}

// The point under the cursor on the horizontal plane z = plane_z (nullopt when the ray from
// the camera misses it): the inverse of render::project_to_pixel for that plane.
std::optional<haptics::Vector3> cursor_on_plane(const render::Camera& camera, int width, int height, double px,
                                                double py, double plane_z) {
  const render::CameraBasis basis = render::camera_basis(camera);
  const double aspect = height > 0 ? static_cast<double>(width) / height : 1.0;
  const double half = std::tan(camera.fov_y_deg * 3.14159265358979 / 360.0);
  const double nx = (2.0 * (px + 0.5) / width - 1.0) * half * aspect;
  const double ny = (1.0 - 2.0 * (py + 0.5) / height) * half;
  double dir[3];
  for (int i = 0; i < 3; ++i) dir[i] = basis.forward[i] + nx * basis.right[i] + ny * basis.up[i];
  if (std::abs(dir[2]) < 1e-9) return std::nullopt;
  const double s = (plane_z - camera.eye[2]) / dir[2];
  if (!(s > 0)) return std::nullopt;
  return haptics::Vector3{camera.eye[0] + s * dir[0], camera.eye[1] + s * dir[1], plane_z};
}

std::filesystem::path numbered(const std::filesystem::path& base, int k) {
  if (k <= 1) return base;
  return base.parent_path() / (base.stem().string() + "_" + std::to_string(k) + base.extension().string());
}

}  // namespace

int run(const RunArgs& args) {
  engine::Scene scene = engine::load_scene(args.scene);
  if (!scene.tool) throw std::runtime_error(args.scene + ": the window drives the scene's tool; this scene has none");
  render::Window window(scene.render.width, scene.render.height, "incise - " + scene.name);
  const int width = window.framebuffer_width(), height = window.framebuffer_height();

  // The devices. The workspace covers the scene with a margin.
  haptics::DeviceLimits limits;
  std::unique_ptr<haptics::Device> device;
  haptics::VirtualDevice* mouse = nullptr;
  haptics::UdpDevice* udp = nullptr;
  double top = 0;
  {
    // Bounds from a throwaway world would cost a build; the scene's camera target and the
    // generators are enough for the workspace: take a generous box around the origin.
    limits.workspace_min = {-0.25, -0.25, -0.05};
    limits.workspace_max = {0.25, 0.25, 0.3};
  }
  if (args.device == "virtual") {
    auto v = std::make_unique<haptics::VirtualDevice>(limits);
    mouse = v.get();
    device = std::move(v);
  } else if (args.device == "replay") {
    if (args.play.empty()) throw std::runtime_error("--device replay needs --play FILE");
    const engine::Trajectory played = engine::read_trajectory(args.play);
    std::vector<haptics::TimedPose> poses;
    for (const auto& s : played.samples) {
      if (!poses.empty() && !(s.time > poses.back().time_s)) continue;
      poses.push_back({s.time, {s.position, s.orientation, s.buttons & engine::kToolButtonEngaged}});
    }
    if (poses.empty()) throw std::runtime_error(args.play + ": holds no sample");
    device = std::make_unique<haptics::ReplayDevice>(std::move(poses), limits);
  } else {
    haptics::UdpDeviceConfig config;
    config.address = args.udp_bind;
    if (args.udp_port < 0 || args.udp_port > 65535) throw std::runtime_error("--udp-port " + std::to_string(args.udp_port) + " is outside [0, 65535]");
    config.port = static_cast<std::uint16_t>(args.udp_port);
    config.limits = limits;
    auto u = std::make_unique<haptics::UdpDevice>(config);
    udp = u.get();
    device = std::move(u);
  }

  std::optional<std::array<int, 4>> drag;
  double drag_depth = 0;
  if (!args.script_drag.empty()) {
    if (!mouse) throw std::runtime_error("--script-drag drives the virtual device: use --device virtual");
    drag = parse_drag(args.script_drag, drag_depth);
    if (args.frames <= 0) throw std::runtime_error("--script-drag needs --frames N (the drag spans them)");
  }

  engine::SessionOptions options;
  options.budget = scene.solver.realtime;
  options.clock = engine::SessionOptions::Clock::realtime;
  options.loop.spin_ns = 300'000;  // spins away the sleep's late wake-ups (physics-choices.md)
  const std::filesystem::path record_base = args.record.empty() ? "recording.traj" : args.record;
  int recordings = 0;

  engine::LatestValue<LiveSnapshot> latest;
  haptics::SpscRing<Request> requests(64);
  std::atomic<bool> stop{false};
  std::atomic<bool> ready{false};
  std::atomic<haptics::HapticLoop*> loop_view{nullptr};  // the panels read the loop's statistics
  std::string physics_error;
  std::size_t triangles_at_start = 0;
  std::string last_recording;

  std::thread physics([&] {
    engine::Scene current = scene;
    std::unique_ptr<engine::HapticSession> session;
    int session_count = 0;
    bool recording = false;
    std::filesystem::path record_file;
    const auto begin = [&](bool record) {
      if (session) {
        loop_view.store(nullptr, std::memory_order_release);
        session->stop();
        if (recording) engine::write_session_summary(*session, record_file.string() + ".json");
        session.reset();
      }
      engine::SessionOptions o = options;
      recording = record;
      if (record) {
        record_file = numbered(record_base, ++recordings);
        o.record = record_file;
        last_recording = record_file.string();
      }
      session = std::make_unique<engine::HapticSession>(current, *device, o);
      loop_view.store(&session->loop(), std::memory_order_release);
      ++session_count;
      if (udp) {
        std::printf("udp device: listening on %s:%u (e.g. incise-bridge --device %s:%u)\n", args.udp_bind.c_str(),
                    static_cast<unsigned>(udp->bound_port()), args.udp_bind.c_str(),
                    static_cast<unsigned>(udp->bound_port()));
        std::fflush(stdout);
      }
    };
    try {
      begin(!args.record.empty());
      const auto& w0 = session->world();
      for (const auto& body : w0.bodies()) triangles_at_start += body.data.surface.size();
      LiveSnapshot::Totals totals;
      int totals_session = -1;
      auto publish = [&](const engine::StepStats& stats, double rtf) {
        const engine::World& world = session->world();
        auto& s = latest.back();
        world.fill_frame(s.frame, width, height);
        s.stats = stats;
        s.time = world.time();
        s.step = world.steps_taken();
        s.real_time_factor = rtf;
        s.cut_events = world.cut_totals().events;
        s.triangles = 0;
        for (const auto& body : world.bodies()) s.triangles += body.data.surface.size();
        s.recording = recording;
        s.recording_file = recording ? record_file.string() : std::string();
        if (totals_session != session_count) totals = {}, totals_session = session_count;
        if (stats.ms_total > 0) totals.add(stats);
        s.session = session_count;
        s.totals = totals;
        latest.publish();
      };
      publish({}, 0);
      ready.store(true, std::memory_order_release);
      while (!stop.load(std::memory_order_acquire)) {
        Request r;
        while (requests.try_pop(r)) {
          if (r.kind == Request::Kind::apply_parameters) {
            for (auto& body : current.bodies) {
              body.material.youngs_modulus = r.youngs_modulus;
              body.material.poisson_ratio = r.poisson_ratio;
            }
            current.solver.tolerance = r.tolerance;
            current.solver.max_iterations = r.max_iterations;
            begin(false);
          } else {
            begin(r.kind == Request::Kind::record_start);
          }
        }
        // step() waits for the haptic tick after the step's end: physics keeps to the hand's
        // time; in real time (solver.realtime) its CG stops when the hand is a step further,
        // otherwise it falls behind when a step takes longer than dt.
        const engine::StepStats stats = session->step();
        // Against the hand's clock, which starts before the world is built (t0 of the session).
        const double wall = 1e-9 * static_cast<double>(haptics::monotonic_now_ns() - session->t0_ns());
        publish(stats, wall > 0 ? session->world().time() / wall : 0);
      }
      loop_view.store(nullptr, std::memory_order_release);
      session->stop();
      if (recording) engine::write_session_summary(*session, record_file.string() + ".json");
    } catch (const std::exception& e) {
      physics_error = e.what();
      loop_view.store(nullptr, std::memory_order_release);
      if (session) {
        try {
          session->stop();
        } catch (const std::exception&) {
        }
      }
    }
    stop.store(true, std::memory_order_release);
  });

  // Panel state (the UI's own, not the simulation's).
  const engine::BodySpec& first_body = scene.bodies.front();
  float youngs_kpa = static_cast<float>(first_body.material.youngs_modulus / 1000);
  float poisson = static_cast<float>(first_body.material.poisson_ratio);
  float tolerance_log = static_cast<float>(std::log10(scene.solver.tolerance));
  int max_iterations = scene.solver.max_iterations;
  Plot period_plot, force_plot, cut_plot, solve_plot, surface_plot, contact_plot;
  std::uint64_t last_ticks = 0;
  auto last_frame_time = SteadyClock::now();
  std::uint64_t last_step_plotted = 0;
  double plane_z = 0;
  bool plane_set = false;
  long frames = 0;
  double draw_ms = 0;  // drawing and presenting the frames (llvmpipe draws on the CPUs physics uses)
  double drag_end_sim_time = -1;
  const auto session_start = SteadyClock::now();

  while (!ready.load(std::memory_order_acquire) && !stop.load(std::memory_order_acquire))
    std::this_thread::sleep_for(std::chrono::milliseconds(5));
  bool drag_done = false;
  for (;;) {
    if (window.should_close() || stop.load(std::memory_order_acquire)) break;
    if (args.frames > 0 && frames >= args.frames) {
      // A scripted drag: keep drawing until physics has caught up with the end of the drag.
      if (!drag || drag_done) break;
    }
    latest.take();
    const LiveSnapshot& s = latest.front();
    if (!plane_set && !s.frame.meshes.empty()) {
      float zmax = -1e30f;
      for (const auto& mesh : s.frame.meshes)
        for (std::size_t i = 2; i < mesh.positions.size(); i += 3) zmax = std::max(zmax, mesh.positions[i]);
      top = zmax;
      plane_z = top + 0.005;
      plane_set = true;
    }

    // The mouse (or the scripted drag) moves the virtual device.
    if (mouse) {
      std::array<double, 2> cursor = window.cursor_position();
      bool engage = false;
      if (drag) {
        const long span = args.frames;
        const double f = static_cast<double>(std::min(frames, span)) / static_cast<double>(span);
        const auto& d = *drag;
        double u = 0;
        if (f < 0.2) {
          plane_z = top + 0.005 - (0.005 + drag_depth) * (f / 0.2);
          engage = true;
        } else if (f < 0.8) {
          u = (f - 0.2) / 0.6;
          plane_z = top - drag_depth;
          engage = true;
        } else {
          u = 1;
          plane_z = top + 0.01;
        }
        cursor = {d[0] + u * (d[2] - d[0]), d[1] + u * (d[3] - d[1])};
        if (frames >= span && drag_end_sim_time < 0)
          drag_end_sim_time = std::chrono::duration<double>(SteadyClock::now() - session_start).count();
      } else if (!window.gui_wants_mouse()) {
        plane_z += 0.002 * window.scroll_delta()[1];
        engage = window.mouse_button_down(render::MouseButton::left);
      }
      if (!window.gui_wants_keyboard() && window.key_down(render::keys::space)) engage = true;
      if (auto p = cursor_on_plane(s.frame.camera, width, height, cursor[0], cursor[1], plane_z)) {
        haptics::DevicePose pose;
        pose.position = *p;
        pose.buttons = engage ? haptics::kButtonEngage : 0;
        mouse->set_pose(pose);
      }
    }
    if (drag && drag_end_sim_time >= 0 && s.time >= drag_end_sim_time + 0.05) drag_done = true;
    if (drag && drag_end_sim_time >= 0 &&
        std::chrono::duration<double>(SteadyClock::now() - session_start).count() > drag_end_sim_time + 300)
      drag_done = true;  // physics far too slow: give up waiting, the report says how far it got

    // Plots: per frame, the mean haptic period since the last frame and the force now; per
    // physics step, its phases.
    haptics::HapticLoop* loop = loop_view.load(std::memory_order_acquire);
    haptics::TickSample tick{};
    haptics::PeriodStatistics periods{};
    bool realtime = false;
    if (loop) {
      tick = loop->latest();
      periods = loop->period_statistics();
      realtime = loop->realtime();
      const std::uint64_t ticks = loop->ticks();
      const auto now = SteadyClock::now();
      const double us = std::chrono::duration<double, std::micro>(now - last_frame_time).count();
      if (ticks > last_ticks && last_ticks > 0) period_plot.push(static_cast<float>(us / static_cast<double>(ticks - last_ticks)));
      last_ticks = ticks;
      last_frame_time = now;
      force_plot.push(static_cast<float>(std::hypot(tick.force[0], tick.force[1], tick.force[2])));
    }
    if (s.step != last_step_plotted) {
      last_step_plotted = s.step;
      cut_plot.push(static_cast<float>(s.stats.ms_ccd + s.stats.ms_topology));
      contact_plot.push(static_cast<float>(s.stats.ms_contact));
      solve_plot.push(static_cast<float>(s.stats.ms_solve));
      surface_plot.push(static_cast<float>(s.stats.ms_surface));
    }

    const auto draw_start = SteadyClock::now();
    window.draw(s.frame, [&] {
      ImGui::SetNextWindowPos(ImVec2(8, 8), ImGuiCond_Always);
      ImGui::SetNextWindowSize(ImVec2(300, 0), ImGuiCond_Always);
      ImGui::SetNextWindowCollapsed(false, ImGuiCond_Once);
      ImGui::SetNextWindowBgAlpha(1.0f);
      ImGui::Begin("incise", nullptr, ImGuiWindowFlags_NoMove);
      ImGui::Text("t = %.2f s  step %llu  x%.2f real time", s.time, static_cast<unsigned long long>(s.step),
                  s.real_time_factor);
      ImGui::Text("%s %s  blade %s  depth %.1f mm", args.device.c_str(), haptics::to_string(tick.state),
                  (tick.pose.buttons & haptics::kButtonEngage) ? "ENGAGED" : "off", 1000 * (top - plane_z));
      ImGui::Text("cuts %ld  triangles %zu", s.cut_events, s.triangles);
      ImGui::Text("CG %d it  r %.1e  %llu over budget", s.stats.cg_iterations, s.stats.cg_residual,
                  static_cast<unsigned long long>(s.totals.over_budget));
      if (ImGui::CollapsingHeader("haptic loop", ImGuiTreeNodeFlags_DefaultOpen)) {
        ImGui::Text("p50 %.0f p99 %.0f max %.0f us >2ms %llu", periods.p50_us, periods.p99_us, periods.max_us,
                    static_cast<unsigned long long>(periods.over_2ms));
        ImGui::Text("%s", realtime ? "SCHED_FIFO" : "normal priority");
        period_plot.draw("period", "us", 800, 1400);
        force_plot.draw("|F|", "N", 0, 1);
      }
      if (ImGui::CollapsingHeader("step time (ms)", ImGuiTreeNodeFlags_DefaultOpen)) {
        cut_plot.draw("cut", "ms", 0, 50);
        contact_plot.draw("contact", "ms", 0, 5);
        solve_plot.draw("solve", "ms", 0, 100);
        surface_plot.draw("surface", "ms", 0, 10);
      }
      if (ImGui::CollapsingHeader("material and solver")) {
        ImGui::SliderFloat("E (kPa)", &youngs_kpa, 0.5f, 100.0f, "%.1f");
        ImGui::SliderFloat("nu", &poisson, 0.0f, 0.49f, "%.2f");
        ImGui::SliderFloat("log10 tolerance", &tolerance_log, -9.0f, -3.0f, "%.1f");
        ImGui::SliderInt("max CG iterations", &max_iterations, 10, 2000);
        if (ImGui::Button("apply (restarts the scene)")) {
          Request r;
          r.kind = Request::Kind::apply_parameters;
          r.youngs_modulus = 1000.0 * youngs_kpa;
          r.poisson_ratio = poisson;
          r.tolerance = std::pow(10.0, tolerance_log);
          r.max_iterations = max_iterations;
          requests.try_push(r);
        }
      }
      if (s.recording) {
        ImGui::TextColored(ImVec4(1, 0.3f, 0.3f, 1), "recording %s", s.recording_file.c_str());
        if (ImGui::Button("stop")) requests.try_push(Request{Request::Kind::record_stop});
      } else if (ImGui::Button("record (restarts the scene)")) {
        requests.try_push(Request{Request::Kind::record_start});
      }
      ImGui::TextDisabled("mouse: blade; wheel: depth");
      ImGui::TextDisabled("left button or space: engage");
      ImGui::End();
    });
    draw_ms += std::chrono::duration<double, std::milli>(SteadyClock::now() - draw_start).count();
    ++frames;
  }
  render::Image shot;
  const bool want_shot = !args.screenshot.empty();
  if (want_shot) shot = window.save_screenshot();
  const LiveSnapshot& final_snapshot = latest.front();
  const double sim_time = final_snapshot.time;
  const long cuts = final_snapshot.cut_events;
  const std::size_t triangles = final_snapshot.triangles;
  stop.store(true, std::memory_order_release);
  physics.join();
  if (want_shot) render::write_png(args.screenshot, shot);
  std::printf("window: %ld frames, physics t = %.3f s, %ld cut events, triangles %zu -> %zu\n", frames, sim_time, cuts,
              triangles_at_start, triangles);
  // Where the time went: the real-time factor, physics' phases per step, the frames' drawing.
  const LiveSnapshot::Totals& t = final_snapshot.totals;
  const double n = std::max<double>(1, static_cast<double>(t.steps));
  std::printf("physics: x%.2f real time, %llu steps, per step %.1f ms (cut %.1f, contact %.1f, solve %.1f with %.1f CG "
              "iterations, surface %.1f), %llu over budget; frames: %.1f ms each to draw\n",
              final_snapshot.real_time_factor, static_cast<unsigned long long>(t.steps), t.ms_step / n, t.ms_cut / n,
              t.ms_contact / n, t.ms_solve / n, t.cg_iterations / n, t.ms_surface / n,
              static_cast<unsigned long long>(t.over_budget), frames > 0 ? draw_ms / static_cast<double>(frames) : 0.0);
  if (!last_recording.empty()) std::printf("recorded %s (summary %s.json)\n", last_recording.c_str(), last_recording.c_str());
  if (!physics_error.empty()) {
    std::fprintf(stderr, "incise: physics stopped: %s\n", physics_error.c_str());
    return 1;
  }
  return 0;
}

}  // namespace incise::app
