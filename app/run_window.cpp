// `incise run`: the interactive window. GLFW wants the main thread, so the main thread is
// the render thread here; physics runs on its own thread in real time and publishes each
// step into a triple buffer the window reads without waiting. The panels write requests
// (pause) into atomics; they never touch physics state.
#include "app/commands.hpp"

#include "engine/publication.hpp"
#include "engine/scene.hpp"
#include "engine/trajectory.hpp"
#include "engine/world.hpp"
#include "render/image.hpp"
#include "render/window.hpp"

#include <imgui.h>

#include <atomic>
#include <chrono>
#include <cstdio>
#include <thread>

namespace incise::app {

namespace {

struct LiveSnapshot {
  render::Frame frame;
  engine::StepStats stats;
  double time = 0;
  std::uint64_t step = 0;
  double real_time_factor = 0;
};

}  // namespace

int run(const RunArgs& args) {
  engine::Scene scene = engine::load_scene(args.scene);
  std::optional<engine::Trajectory> trajectory;
  if (scene.tool && scene.tool->trajectory) trajectory = engine::read_trajectory(*scene.tool->trajectory);
  engine::World world(scene, std::move(trajectory));
  render::Window window(scene.render.width, scene.render.height, "incise - " + scene.name);

  engine::LatestValue<LiveSnapshot> latest;
  std::atomic<bool> stop{false};
  std::atomic<bool> paused{false};
  std::string physics_error;
  const int width = window.framebuffer_width(), height = window.framebuffer_height();
  {
    auto& first = latest.back();
    world.fill_frame(first.frame, width, height);
    latest.publish();
  }
  std::thread physics([&] {
    using Clock = std::chrono::steady_clock;
    auto start = Clock::now();
    double sim_at_start = 0;
    try {
      while (!stop.load(std::memory_order_acquire)) {
        if (paused.load(std::memory_order_acquire)) {
          std::this_thread::sleep_for(std::chrono::milliseconds(5));
          start = Clock::now();
          sim_at_start = world.time();
          continue;
        }
        // Real time: never run ahead of the wall clock; when a step is slower than dt the
        // simulation falls behind and the panel shows the real-time factor.
        double wall = std::chrono::duration<double>(Clock::now() - start).count();
        double ahead = (world.time() - sim_at_start) - wall;
        if (ahead > 0) {
          std::this_thread::sleep_for(std::chrono::duration<double>(ahead));
          continue;
        }
        auto stats = world.step();
        auto& s = latest.back();
        world.fill_frame(s.frame, width, height);
        s.stats = stats;
        s.time = world.time();
        s.step = world.steps_taken();
        double elapsed = std::chrono::duration<double>(Clock::now() - start).count();
        s.real_time_factor = elapsed > 0 ? (world.time() - sim_at_start) / elapsed : 0;
        latest.publish();
      }
    } catch (const std::exception& e) {
      physics_error = e.what();
    }
    stop.store(true, std::memory_order_release);
  });

  long frames = 0;
  while (!window.should_close() && (args.frames <= 0 || frames < args.frames)) {
    latest.take();
    const LiveSnapshot& s = latest.front();
    window.draw(s.frame, [&] {
      ImGui::Begin("incise");
      ImGui::Text("scene %s", scene.name.c_str());
      ImGui::Text("t = %.3f s  step %llu", s.time, static_cast<unsigned long long>(s.step));
      ImGui::Text("step %.2f ms (solve %.2f)  x%.2f real time", s.stats.ms_total, s.stats.ms_solve, s.real_time_factor);
      ImGui::Text("CG %d iterations, residual %.2e", s.stats.cg_iterations, s.stats.cg_residual);
      ImGui::Text("tool force (%.3f, %.3f, %.3f) N, %d contacts", s.stats.tool_force[0], s.stats.tool_force[1],
                  s.stats.tool_force[2], s.stats.contacts);
      bool p = paused.load();
      if (ImGui::Checkbox("pause", &p)) paused.store(p);
      ImGui::End();
    });
    ++frames;
    if (stop.load(std::memory_order_acquire)) break;
  }
  if (!args.screenshot.empty()) render::write_png(args.screenshot, window.save_screenshot());
  stop.store(true, std::memory_order_release);
  physics.join();
  if (!physics_error.empty()) {
    std::fprintf(stderr, "incise: physics stopped: %s\n", physics_error.c_str());
    return 1;
  }
  return 0;
}

}  // namespace incise::app
