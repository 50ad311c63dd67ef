// The window's physics thread (`incise run`, app/run_window.cpp): an engine::HapticSession that
// drains the haptic loop's ticks as the blade's sweep, steps, and publishes a LiveSnapshot for
// the render thread (a triple buffer: neither waits for the other). The render thread's panels
// write Requests into a single-producer queue it reads between steps; a parameter change or a
// recording restarts the session from the scene's initial state, so every recording starts at
// t = 0 and replays headless to the same state (its summary FILE.json says how many steps).
#pragma once

#include "engine/haptic_session.hpp"
#include "engine/publication.hpp"
#include "engine/scene.hpp"
#include "engine/world.hpp"
#include "haptics/spsc_ring.hpp"
#include "haptics/udp_device.hpp"
#include "render/frame.hpp"

#include <atomic>
#include <cstdint>
#include <filesystem>
#include <memory>
#include <string>

namespace incise::app {

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
    void add(const engine::StepStats& stats);
  } totals;
};

// Requests from the panels to the physics thread (plain values: the queue never allocates).
struct Request {
  enum class Kind { apply_parameters, record_start, record_stop } kind = Kind::apply_parameters;
  double youngs_modulus = 0, poisson_ratio = 0, tolerance = 0;
  int max_iterations = 0;
};

// What the two threads share. The strings and the triangle count are written by the physics
// thread and read by the render thread only after joining it.
struct WindowShared {
  engine::LatestValue<LiveSnapshot> latest;
  haptics::SpscRing<Request> requests{64};
  std::atomic<bool> stop{false};   // either thread: the window closed, or physics stopped
  std::atomic<bool> ready{false};  // the first snapshot is published
  std::atomic<haptics::HapticLoop*> loop_view{nullptr};  // the panels read the loop's statistics
  std::string physics_error;
  std::size_t triangles_at_start = 0;
  std::string last_recording;
};

struct WindowPhysicsSettings {
  engine::SessionOptions options;    // real-time clock and budget
  std::filesystem::path record_base; // recording.traj, or --record; numbered from the second on
  bool record_at_start = false;
  int width = 0, height = 0;         // of the frames it fills
  haptics::UdpDevice* udp = nullptr; // says where it listens at each (re)start
  std::string udp_bind;
};

// The physics thread's body: runs until shared.stop, then stops the session (writing the
// recording's summary) and sets shared.stop itself; an error goes to shared.physics_error.
void run_window_physics(const engine::Scene& scene, haptics::Device& device, const WindowPhysicsSettings& settings,
                        WindowShared& shared);

}  // namespace incise::app
