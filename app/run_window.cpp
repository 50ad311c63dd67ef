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
#include "app/window_physics.hpp"

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

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <thread>

namespace incise::app {

namespace {

using SteadyClock = std::chrono::steady_clock;

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


// The device the window reads: the mouse (a VirtualDevice), a recorded trajectory, or a UDP
// bridge. The workspace covers the scene with a margin: bounds from a throwaway world would
// cost a build; a generous box around the origin is enough.
struct Devices {
  std::unique_ptr<haptics::Device> device;
  haptics::VirtualDevice* mouse = nullptr;
  haptics::UdpDevice* udp = nullptr;
};

Devices open_device(const RunArgs& args) {
  haptics::DeviceLimits limits;
  limits.workspace_min = {-0.25, -0.25, -0.05};
  limits.workspace_max = {0.25, 0.25, 0.3};
  Devices d;
  if (args.device == "virtual") {
    auto v = std::make_unique<haptics::VirtualDevice>(limits);
    d.mouse = v.get();
    d.device = std::move(v);
  } else if (args.device == "replay") {
    if (args.play.empty()) throw std::runtime_error("--device replay needs --play FILE");
    const engine::Trajectory played = engine::read_trajectory(args.play);
    std::vector<haptics::TimedPose> poses;
    for (const auto& s : played.samples) {
      if (!poses.empty() && !(s.time > poses.back().time_s)) continue;
      poses.push_back({s.time, {s.position, s.orientation, s.buttons & engine::kToolButtonEngaged}});
    }
    if (poses.empty()) throw std::runtime_error(args.play + ": holds no sample");
    d.device = std::make_unique<haptics::ReplayDevice>(std::move(poses), limits);
  } else {
    haptics::UdpDeviceConfig config;
    config.address = args.udp_bind;
    if (args.udp_port < 0 || args.udp_port > 65535) throw std::runtime_error("--udp-port " + std::to_string(args.udp_port) + " is outside [0, 65535]");
    config.port = static_cast<std::uint16_t>(args.udp_port);
    config.limits = limits;
    auto u = std::make_unique<haptics::UdpDevice>(config);
    d.udp = u.get();
    d.device = std::move(u);
  }
  return d;
}

// Turns the cursor (or a scripted drag, for tests) into the virtual device's pose: the point
// under the cursor on a horizontal plane, first 5 mm above the body's top, moved by the wheel.
class MouseDriver {
 public:
  MouseDriver(const RunArgs& args, bool mouse) : span_(args.frames) {
    if (args.script_drag.empty()) return;
    if (!mouse) throw std::runtime_error("--script-drag drives the virtual device: use --device virtual");
    drag_ = parse_drag(args.script_drag, drag_depth_);
    if (args.frames <= 0) throw std::runtime_error("--script-drag needs --frames N (the drag spans them)");
  }

  // Once per frame, before drawing it.
  void update(const LiveSnapshot& s, render::Window& window, haptics::VirtualDevice* mouse, long frames, int width,
              int height) {
    if (!plane_set_ && !s.frame.meshes.empty()) {
      float zmax = -1e30f;
      for (const auto& mesh : s.frame.meshes)
        for (std::size_t i = 2; i < mesh.positions.size(); i += 3) zmax = std::max(zmax, mesh.positions[i]);
      top_ = zmax;
      plane_z_ = top_ + 0.005;
      plane_set_ = true;
    }
    if (mouse) {
      std::array<double, 2> cursor = window.cursor_position();
      bool engage = false;
      if (drag_) {
        cursor = scripted(frames, engage);
      } else if (!window.gui_wants_mouse()) {
        plane_z_ += 0.002 * window.scroll_delta()[1];
        engage = window.mouse_button_down(render::MouseButton::left);
      }
      if (!window.gui_wants_keyboard() && window.key_down(render::keys::space)) engage = true;
      if (auto p = cursor_on_plane(s.frame.camera, width, height, cursor[0], cursor[1], plane_z_)) {
        haptics::DevicePose pose;
        pose.position = *p;
        pose.buttons = engage ? haptics::kButtonEngage : 0;
        mouse->set_pose(pose);
      }
    }
    const double since_start = std::chrono::duration<double>(SteadyClock::now() - start_).count();
    if (drag_ && drag_end_time_ >= 0 && s.time >= drag_end_time_ + 0.05) drag_done_ = true;
    // Physics far too slow: give up waiting, the summary says how far it got.
    if (drag_ && drag_end_time_ >= 0 && since_start > drag_end_time_ + 300) drag_done_ = true;
  }

  // With --frames: a scripted drag keeps drawing until physics has caught up with its end.
  bool done(long frames) const { return span_ > 0 && frames >= span_ && (!drag_ || drag_done_); }
  double depth_mm() const { return 1000 * (top_ - plane_z_); }

 private:
  // Down to the drag's depth over the first fifth of the frames, across over the next three,
  // lifted out for the last; the end's wall time marks when physics has to reach.
  std::array<double, 2> scripted(long frames, bool& engage) {
    const double f = static_cast<double>(std::min(frames, span_)) / static_cast<double>(span_);
    const auto& d = *drag_;
    double u = 0;
    if (f < 0.2) {
      plane_z_ = top_ + 0.005 - (0.005 + drag_depth_) * (f / 0.2);
      engage = true;
    } else if (f < 0.8) {
      u = (f - 0.2) / 0.6;
      plane_z_ = top_ - drag_depth_;
      engage = true;
    } else {
      u = 1;
      plane_z_ = top_ + 0.01;
    }
    if (frames >= span_ && drag_end_time_ < 0)
      drag_end_time_ = std::chrono::duration<double>(SteadyClock::now() - start_).count();
    return {d[0] + u * (d[2] - d[0]), d[1] + u * (d[3] - d[1])};
  }

  long span_ = 0;
  std::optional<std::array<int, 4>> drag_;
  double drag_depth_ = 0;
  double drag_end_time_ = -1;  // s since start_ when the drag ended
  bool drag_done_ = false;
  double top_ = 0, plane_z_ = 0;
  bool plane_set_ = false;
  const SteadyClock::time_point start_ = SteadyClock::now();
};

// The panel: what the simulation is doing, the haptic loop's period and force, the step's
// phases, and the requests (material and solver, record/stop). Its sliders are the UI's own
// state, not the simulation's.
class Panel {
 public:
  Panel(const engine::Scene& scene, const RunArgs& args)
      : device_(args.device),
        youngs_kpa_(static_cast<float>(scene.bodies.front().material.youngs_modulus / 1000)),
        poisson_(static_cast<float>(scene.bodies.front().material.poisson_ratio)),
        tolerance_log_(static_cast<float>(std::log10(scene.solver.tolerance))),
        max_iterations_(scene.solver.max_iterations) {}

  // Per frame, the mean haptic period since the last frame and the force now; per physics
  // step, its phases.
  void sample(const LiveSnapshot& s, haptics::HapticLoop* loop) {
    tick_ = {};
    periods_ = {};
    realtime_ = false;
    if (loop) {
      tick_ = loop->latest();
      periods_ = loop->period_statistics();
      realtime_ = loop->realtime();
      const std::uint64_t ticks = loop->ticks();
      const auto now = SteadyClock::now();
      const double us = std::chrono::duration<double, std::micro>(now - last_frame_time_).count();
      if (ticks > last_ticks_ && last_ticks_ > 0) period_plot_.push(static_cast<float>(us / static_cast<double>(ticks - last_ticks_)));
      last_ticks_ = ticks;
      last_frame_time_ = now;
      force_plot_.push(static_cast<float>(std::hypot(tick_.force[0], tick_.force[1], tick_.force[2])));
      cutting_plot_.push(
          static_cast<float>(std::hypot(tick_.cutting_force[0], tick_.cutting_force[1], tick_.cutting_force[2])));
    }
    if (s.step != last_step_plotted_) {
      last_step_plotted_ = s.step;
      cut_plot_.push(static_cast<float>(s.stats.ms_ccd + s.stats.ms_topology));
      contact_plot_.push(static_cast<float>(s.stats.ms_contact));
      solve_plot_.push(static_cast<float>(s.stats.ms_solve));
      surface_plot_.push(static_cast<float>(s.stats.ms_surface));
    }
  }

  void draw(const LiveSnapshot& s, double depth_mm, haptics::SpscRing<Request>& requests) {
    ImGui::SetNextWindowPos(ImVec2(8, 8), ImGuiCond_Always);
    ImGui::SetNextWindowSize(ImVec2(300, 0), ImGuiCond_Always);
    ImGui::SetNextWindowCollapsed(false, ImGuiCond_Once);
    ImGui::SetNextWindowBgAlpha(1.0f);
    ImGui::Begin("incise", nullptr, ImGuiWindowFlags_NoMove);
    ImGui::Text("t = %.2f s  step %llu  x%.2f real time", s.time, static_cast<unsigned long long>(s.step), s.real_time_factor);
    ImGui::Text("%s %s  blade %s  depth %.1f mm", device_.c_str(), haptics::to_string(tick_.state),
                (tick_.pose.buttons & haptics::kButtonEngage) ? "ENGAGED" : "off", depth_mm);
    ImGui::Text("cuts %ld  triangles %zu", s.cut_events, s.triangles);
    ImGui::Text("CG %d it  r %.1e  %llu over budget", s.stats.cg_iterations, s.stats.cg_residual,
                static_cast<unsigned long long>(s.totals.over_budget));
    if (ImGui::CollapsingHeader("haptic loop", ImGuiTreeNodeFlags_DefaultOpen)) {
      ImGui::Text("p50 %.0f p99 %.0f max %.0f us >2ms %llu", periods_.p50_us, periods_.p99_us, periods_.max_us,
                  static_cast<unsigned long long>(periods_.over_2ms));
      ImGui::Text("%s", realtime_ ? "SCHED_FIFO" : "normal priority");
      period_plot_.draw("period", "us", 800, 1400);
      force_plot_.draw("|F|", "N", 0, 3);
      cutting_plot_.draw("cutting", "N", 0, 3);  // the tissue's resistance to the blade (haptics/cutting_proxy.hpp)
      ImGui::Text("energy to the device %.2e J", tick_.device_energy);
    }
    if (ImGui::CollapsingHeader("step time (ms)", ImGuiTreeNodeFlags_DefaultOpen)) {
      cut_plot_.draw("cut", "ms", 0, 50);
      contact_plot_.draw("contact", "ms", 0, 5);
      solve_plot_.draw("solve", "ms", 0, 100);
      surface_plot_.draw("surface", "ms", 0, 10);
    }
    if (ImGui::CollapsingHeader("material and solver")) draw_parameters(requests);
    if (s.recording) {
      ImGui::TextColored(ImVec4(1, 0.3f, 0.3f, 1), "recording %s", s.recording_file.c_str());
      if (ImGui::Button("stop")) requests.try_push(Request{Request::Kind::record_stop});
    } else if (ImGui::Button("record (restarts the scene)")) {
      requests.try_push(Request{Request::Kind::record_start});
    }
    ImGui::TextDisabled("mouse: blade; wheel: depth");
    ImGui::TextDisabled("left button or space: engage");
    ImGui::End();
  }

 private:
  void draw_parameters(haptics::SpscRing<Request>& requests) {
    ImGui::SliderFloat("E (kPa)", &youngs_kpa_, 0.5f, 100.0f, "%.1f");
    ImGui::SliderFloat("nu", &poisson_, 0.0f, 0.49f, "%.2f");
    ImGui::SliderFloat("log10 tolerance", &tolerance_log_, -9.0f, -3.0f, "%.1f");
    ImGui::SliderInt("max CG iterations", &max_iterations_, 10, 2000);
    if (!ImGui::Button("apply (restarts the scene)")) return;
    Request r;
    r.kind = Request::Kind::apply_parameters;
    r.youngs_modulus = 1000.0 * youngs_kpa_;
    r.poisson_ratio = poisson_;
    r.tolerance = std::pow(10.0, tolerance_log_);
    r.max_iterations = max_iterations_;
    requests.try_push(r);
  }

  std::string device_;
  float youngs_kpa_, poisson_, tolerance_log_;
  int max_iterations_;
  Plot period_plot_, force_plot_, cutting_plot_, cut_plot_, solve_plot_, surface_plot_, contact_plot_;
  std::uint64_t last_ticks_ = 0, last_step_plotted_ = 0;
  SteadyClock::time_point last_frame_time_ = SteadyClock::now();
  haptics::TickSample tick_{};
  haptics::PeriodStatistics periods_{};
  bool realtime_ = false;
};

// Where the time went: the real-time factor, physics' phases per step, the frames' drawing.
void print_summary(const LiveSnapshot& last, const WindowShared& shared, long frames, double draw_ms) {
  std::printf("window: %ld frames, physics t = %.3f s, %ld cut events, triangles %zu -> %zu\n", frames, last.time,
              last.cut_events, shared.triangles_at_start, last.triangles);
  const LiveSnapshot::Totals& t = last.totals;
  const double n = std::max<double>(1, static_cast<double>(t.steps));
  std::printf("physics: x%.2f real time, %llu steps, per step %.1f ms (cut %.1f, contact %.1f, solve %.1f with %.1f CG "
              "iterations, surface %.1f), %llu over budget; frames: %.1f ms each to draw\n",
              last.real_time_factor, static_cast<unsigned long long>(t.steps), t.ms_step / n, t.ms_cut / n,
              t.ms_contact / n, t.ms_solve / n, t.cg_iterations / n, t.ms_surface / n,
              static_cast<unsigned long long>(t.over_budget), frames > 0 ? draw_ms / static_cast<double>(frames) : 0.0);
  if (!shared.last_recording.empty())
    std::printf("recorded %s (summary %s.json)\n", shared.last_recording.c_str(), shared.last_recording.c_str());
}

}  // namespace

int run(const RunArgs& args) {
  engine::Scene scene = engine::load_scene(args.scene);
  if (!scene.tool) throw std::runtime_error(args.scene + ": the window drives the scene's tool; this scene has none");
  render::Window window(scene.render.width, scene.render.height, "incise - " + scene.name);
  const int width = window.framebuffer_width(), height = window.framebuffer_height();
  Devices devices = open_device(args);
  MouseDriver driver(args, devices.mouse != nullptr);
  Panel panel(scene, args);

  WindowPhysicsSettings settings;
  settings.options.budget = scene.solver.realtime;
  settings.options.clock = engine::SessionOptions::Clock::realtime;
  settings.options.loop.spin_ns = 300'000;  // spins away the sleep's late wake-ups (physics-choices.md)
  settings.record_base = args.record.empty() ? "recording.traj" : args.record;
  settings.record_at_start = !args.record.empty();
  settings.width = width;
  settings.height = height;
  settings.udp = devices.udp;
  settings.udp_bind = args.udp_bind;
  WindowShared shared;
  std::thread physics([&] { run_window_physics(scene, *devices.device, settings, shared); });

  while (!shared.ready.load(std::memory_order_acquire) && !shared.stop.load(std::memory_order_acquire))
    std::this_thread::sleep_for(std::chrono::milliseconds(5));
  long frames = 0;
  double draw_ms = 0;  // drawing and presenting the frames (llvmpipe draws on the CPUs physics uses)
  while (!window.should_close() && !shared.stop.load(std::memory_order_acquire) && !driver.done(frames)) {
    shared.latest.take();
    const LiveSnapshot& s = shared.latest.front();
    driver.update(s, window, devices.mouse, frames, width, height);
    panel.sample(s, shared.loop_view.load(std::memory_order_acquire));
    const auto draw_start = SteadyClock::now();
    window.draw(s.frame, [&] { panel.draw(s, driver.depth_mm(), shared.requests); });
    draw_ms += std::chrono::duration<double, std::milli>(SteadyClock::now() - draw_start).count();
    ++frames;
  }
  render::Image shot;
  if (!args.screenshot.empty()) shot = window.save_screenshot();
  shared.stop.store(true, std::memory_order_release);
  physics.join();
  if (!args.screenshot.empty()) render::write_png(args.screenshot, shot);
  print_summary(shared.latest.front(), shared, frames, draw_ms);
  if (!shared.physics_error.empty()) {
    std::fprintf(stderr, "incise: physics stopped: %s\n", shared.physics_error.c_str());
    return 1;
  }
  return 0;
}

}  // namespace incise::app
