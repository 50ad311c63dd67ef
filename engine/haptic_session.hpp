// The engine's side of the haptic loop (issue 5; the contract is haptics/haptic_loop.hpp's
// header). A HapticSession owns the Device, the ContactChannel, the HapticLoop and the World:
//
//   haptic thread (1 kHz)                 physics (the caller of step())
//   device pose, force  ──SPSC ring──▶    drain: every tick since the last step, recorded to the
//                                         trajectory file, fed to the World as its tool input;
//                                         World::step(): the samples in (t_k-1, t_k] are the
//                                         blade's swept path (CCD, topology, solve, surface);
//   force ◀── ContactModel ◀──────────    build_contact_model() from the surface after the step
//                                         (so in the step a cut changes the topology, the model
//                                         already describes the cut surface), validate, publish.
//
// Time. The session's time is the haptic loop's: t = 0 at the first tick, every tick's sample
// is stamped with its own time. Step k covers (t_k-1, t_k] of that time, as a replay of the
// recording would, so before stepping, physics waits until a tick later than t_k has arrived
// (the sample after the step's end is sample_at's right neighbour). Physics waits on the
// haptic loop, never the reverse. When a step is slower than dt the simulation falls behind
// the hand (the window shows the real-time factor) but never drops or reorders a sample, so a
// live session and the headless replay of its recording take identical steps: same cuts, same
// triangle count, same state hash.
//
// Two clocks. realtime: the loop runs on its own thread (clock_nanosleep to absolute
// deadlines). simulated: no thread; step() calls HapticLoop::tick(t) itself at every period
// of simulated time, calling the `script` hook before each tick so a scripted device can set
// its pose for that instant: deterministic, for tests and `incise session`.
#pragma once

#include "engine/scene.hpp"
#include "engine/trajectory.hpp"
#include "engine/world.hpp"
#include "haptics/contact_model.hpp"
#include "haptics/haptic_loop.hpp"

#include <nlohmann/json.hpp>

#include <cstdint>
#include <filesystem>
#include <functional>
#include <memory>
#include <optional>
#include <string>
#include <vector>

namespace incise::engine {

// The contact linearisation physics hands the haptic loop (haptics/contact_model.hpp), built
// from the world after a step. The tool's contact points are its tip (sphere), points along
// its axis (capsule) or along its cutting edge (blade, at most ContactModel::kCapacity). For
// each, the nearest surface triangle within `search_radius` gives a half-space: the closest
// point and the face's outward normal, shifted by the point's offset from the tool's reference
// point (the device position), so the loop evaluates it at the device position directly.
// Stiffness: the tool's penalty stiffness (tool.stiffness; a blade without one gets
// kDefaultBladeStiffness), shared among the tool's points so the total does not depend on how
// many there are. Compliance: the tissue's own, as an elastic half-space under a punch the
// size of the body's resolution r (Boussinesq: k = 2 E r / (1 - nu^2)), so a soft organ feels
// soft however stiff the penalty. Proxy: the tool as physics placed it, with its velocity,
// but has_proxy stays false (no virtual coupling): see build_contact_model.
struct ContactBuild {
  double search_radius = 0;  // m; <= 0: three times the largest body resolution
  std::int64_t time_ns = 0;  // haptic clock time of the step's end (the proxy's time)
  std::uint64_t step = 0;
  std::array<double, 3> proxy_velocity{};  // m/s
  // The model's domain (ContactModel::valid_radius) around the tool's position; <= 0: the
  // search radius (the nearest surface is only looked for that far).
  double valid_radius = 0;
  // The blade's last cutting direction (unit; zero: none yet), for a step in which it engaged
  // the tissue without advancing.
  std::array<double, 3> cutting_direction{};
};
inline constexpr double kDefaultBladeStiffness = 400;  // N/m, whole edge
haptics::ContactModel build_contact_model(const World& world, const ContactBuild& build);

// A needle's term (haptics::NeedleResistance; engine/needle_haptics.cpp), zero when the needle
// is out of the tissue. Along the shaft: insert_force the cutting zone's intensity C (its
// members' k_c by their inverse-distance shares, whether or not the needle advanced over the
// step: the hand meets the same tissue ahead) plus the kinetic friction of the gripping nodes,
// retract_force that friction alone. Across: each gripping node (and the tip while its cutting
// zone holds tissue) a spring of its virtual particle's stick_stiffness in series with the
// tissue's compliance (the contacts' Boussinesq punch), the stiffness their sum, the line through
// the device's position shifted by their mean lateral pull (their virtual particles' offsets
// from their nodes, across the axis), so the force at the step's pose is the tissue's grip.
// A needle has no surface contacts: it enters the tissue through its zones.
haptics::NeedleResistance needle_resistance(const World& world);

// A tick as a trajectory sample: time since t0, pose, buttons, the force rendered. The device
// state goes into buttons bits 8-9 and the clamp into bit 10 (docs/trajectory.md: bits above
// 0 are free for devices); the World reads bit 0 only.
ToolSample to_tool_sample(const haptics::TickSample& tick, std::int64_t t0_ns);
inline constexpr std::uint32_t kButtonsDeviceStateShift = 8;
inline constexpr std::uint32_t kButtonClamped = 1u << 10;

struct SessionOptions {
  enum class Clock { realtime, simulated };
  Clock clock = Clock::simulated;
  haptics::HapticLoopConfig loop{};
  std::optional<std::filesystem::path> record;  // every tick to this trajectory file
  std::size_t record_chunk = 250;               // samples per chunk (the most an abrupt stop loses)
  bool keep_ticks = false;                      // keep every tick in ticks() (bench, tests)
  // simulated: called with the tick's time (s since t0) before each tick.
  std::function<void(double)> script;
  double realtime_stall_s = 2.0;  // realtime: no tick for this long is an error
  // Real time (engine/real_time_budget.hpp; the commands set it from solver.realtime): each
  // step's CG stops when its time is up, so the tissue never falls behind the hand. On the
  // realtime clock step k must be done when the hand reaches t_k + dt (a step late is caught
  // up by the next); on the simulated clock within dt of wall time from its start. The stops
  // go to the recording, whose replay repeats them.
  bool budget = false;
  double budget_share = 1.0;  // of dt: how much later than the above the step may end (tests force stops with ~0)
};

class HapticSession {
 public:
  // Opens the device, takes the first tick (t = 0) and builds the World with it as the tool's
  // first sample; realtime sessions then start the loop thread. Throws std::runtime_error
  // when the scene has no tool, or what the device, the world or the recording throws.
  HapticSession(const Scene& scene, haptics::Device& device, SessionOptions options);
  ~HapticSession();  // stop()
  HapticSession(const HapticSession&) = delete;
  HapticSession& operator=(const HapticSession&) = delete;

  // One physics step on the samples up to its end; publishes the ContactModel it leaves.
  StepStats step();
  // Stops the loop thread, records what is left in the ring, closes the recording and the
  // device. Idempotent.
  void stop();

  World& world() { return *world_; }
  const World& world() const { return *world_; }
  haptics::HapticLoop& loop() { return *loop_; }
  const std::vector<haptics::TickSample>& ticks() const { return ticks_; }
  // cut_steps()[k] == 1 when step k changed the topology (index 0: the initial state).
  const std::vector<std::uint8_t>& cut_steps() const { return cut_steps_; }
  std::uint64_t samples_recorded() const { return samples_recorded_; }
  // Real time: the steps whose CG the budget stopped, and the worst residual they left.
  std::uint64_t steps_over_budget() const { return steps_over_budget_; }
  double residual_max_over_budget() const { return residual_max_over_budget_; }
  bool budget() const { return options_.budget; }
  std::int64_t t0_ns() const { return t0_ns_; }
  const haptics::ContactModel& last_model() const { return last_model_; }

 private:
  void take(const haptics::TickSample& tick);
  void drain();
  void publish(std::uint64_t step);
  std::int64_t step_deadline_ns(double end) const;  // 0 without a budget

  SessionOptions options_;
  haptics::Device& device_;
  haptics::ContactChannel channel_;
  std::unique_ptr<haptics::HapticLoop> loop_;
  std::unique_ptr<World> world_;
  std::optional<TrajectoryWriter> writer_;
  std::int64_t t0_ns_ = 0;
  std::int64_t next_tick_ns_ = 0;  // simulated clock
  std::vector<ToolSample> pending_;
  std::vector<haptics::TickSample> ticks_;
  std::vector<std::uint8_t> cut_steps_{0};
  std::uint64_t samples_recorded_ = 0;
  std::uint64_t steps_over_budget_ = 0;
  double residual_max_over_budget_ = 0;
  std::array<double, 3> previous_proxy_{};
  haptics::ContactModel last_model_{};
  bool stopped_ = false;
};

// Force continuity (issue 5): |F_i - F_i-1| per millisecond between consecutive ticks, the
// largest at the first tick that uses a model rebuilt in a cut step, at the first tick of any
// other new model, and between publications. A tick less than the loop's period `period_ms`
// after the one before counts as a whole period: after a late wake-up the loop keeps its
// deadlines and ticks again within microseconds, and the small change of that short interval
// (0.011 N in 30 us after a 2.97 ms stall, `bench haptics`) read 0.36 N/ms over it, though the
// device holds each force a period or more.
struct ForceJumps {
  double at_cut_max = 0;          // N/ms
  double at_publication_max = 0;  // new model, no cut
  double between_max = 0;         // same model as the tick before
  std::int64_t at_cut_max_ns = 0, at_publication_max_ns = 0, between_max_ns = 0;  // when (tick time)
  std::size_t cut_ticks = 0, publication_ticks = 0, ticks = 0;
};
ForceJumps force_jumps(const std::vector<haptics::TickSample>& ticks, const std::vector<std::uint8_t>& cut_steps,
                       double period_ms = 1.0);

// What a session did, for session.json and the summary beside a recording (FILE.json): steps,
// simulated time, ticks recorded, state hash, surface triangles, cut events, and the force
// jumps when ticks were kept. `incise replay SCENE --trajectory FILE --steps <steps>` of the
// recording reproduces state_hash and surface_triangles.
nlohmann::json session_summary(const HapticSession& session);
// Writes session_summary() to file (std::runtime_error naming it when it cannot).
void write_session_summary(const HapticSession& session, const std::filesystem::path& file);

}  // namespace incise::engine
