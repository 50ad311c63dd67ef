// The 1 kHz haptic loop (issue 5): its own std::thread on absolute deadlines, never waiting on
// physics or rendering. Each tick:
//   pose   = device.read_pose()                      (state() ok / lost)
//   model  = the newest ContactModel physics published (TripleBuffer read: no lock, no copy)
//   force  = virtual coupling to the tool proxy + contact_force(model, device position)
//   force  = 0 unless the device is ok; clamped to |force| <= device.limits().max_force
//   force += the passivity controller's damper while the device holds net energy (passivity.hpp)
//   device.write_force(force); push the TickSample into the SPSC ring physics drains.
//
// Integration (the engine's side: engine/haptic_session.hpp, HapticSession):
//   - The session owns the ContactChannel, the HapticLoop and the World and drives a Device the
//     caller owns; it opens the device, start()s the loop (realtime clock), and stop()s it
//     before closing the device.
//   - The physics thread, at the start of each step, drains samples() (the consumer side of
//     the ring; one consumer only), records each tick and feeds every pose since its last step
//     to World::append_tool_samples as the blade's swept path; it waits for the tick after the
//     step's end, so a live step equals a replay's. ring_overflows() counts samples lost when
//     it has not drained for ring_capacity ticks.
//   - At the end of each step, including the step a cut changes the topology, physics builds
//     the ContactModel from the surface the step left (engine::build_contact_model: half-spaces
//     at the nearest surface points of the tool's edge, penalty stiffness in series with the
//     tissue's compliance), validate()s and publish()es it; the next tick starts fading it
//     in over the interval between publications (HapticLoopConfig::blend_ns), what the tick
//     before rendered fading out (model_fade.hpp: the model before it, or the blend it was
//     still fading in with).
//   - Headless sessions (simulated clock: tests, `incise session`) do not start the thread:
//     the session calls tick(t) with simulated time between physics steps, so two runs give
//     identical samples.
//   - The window (app/run_window.cpp) reads latest() and period_statistics() for its plots;
//     the VirtualDevice's set_pose() is its mouse input.
//   - Recording: the session, the consumer of samples(), writes each TickSample (pose,
//     buttons, force, device state, time) to the trajectory file (engine::to_tool_sample).
#pragma once

#include <atomic>
#include <cstdint>
#include <thread>

#include "haptics/contact_model.hpp"
#include "haptics/cutting_proxy.hpp"
#include "haptics/needle_proxy.hpp"
#include "haptics/device.hpp"
#include "haptics/model_fade.hpp"
#include "haptics/passivity.hpp"
#include "haptics/period_statistics.hpp"
#include "haptics/seqlock.hpp"
#include "haptics/spsc_ring.hpp"

namespace incise::haptics {

// Virtual coupling (Colgate, Stanley & Brown 1995; Adams & Hannaford 1999): a spring-damper
// between the device and the tool proxy that physics simulates.
//
// Why the damping is what it is. A spring of stiffness K rendered by a sampled loop of period T
// with a zero-order hold lags the position by half a sample on average, which acts as a
// negative damping of about K T / 2: the hold injects energy. Colgate & Schenkel ("Passivity
// of a class of sampled-data systems", 1997) make this exact: a virtual spring K with damper
// B is passive iff b > K T / 2 + |B|, b being the damping that acts continuously. The coupling
// damper must therefore at least cancel the hold's K T / 2, so validate() refuses
// damping < K T / 2, and the default is damping = K T, a factor-two margin because the damper
// sees a filtered backward-difference velocity that lags too. Strictly, in Colgate's
// inequality the sampled damper counts against passivity (the |B| term): what carries the rest
// is the device's own friction b, so on a real device with little friction the knob is the
// stiffness (keep K below 2 (b - B) / T), and the force clamp bounds what energy remains.
// The contact springs get the same rule: each active contact's normal force has a damper of
// k_eff T (contact_model.hpp).
struct CouplingParameters {
  double stiffness = 300;  // N/m
  double damping = -1;     // N s/m; negative: the default, stiffness * period (see above)
};

struct HapticLoopConfig {
  double rate_hz = 1000;
  CouplingParameters coupling{};
  // SCHED_FIFO at this priority when the process may (CAP_SYS_NICE or an rtprio limit);
  // otherwise the loop runs at normal priority and realtime() says so. Never an error.
  bool realtime_priority = true;
  int realtime_priority_level = 80;
  // Pin the loop's thread to this CPU (pthread_setaffinity_np) when >= 0 and the process may;
  // otherwise it runs where the scheduler puts it and cpu() says -1. Never an error. A bare
  // loop pinned to the same CPU beside it sees a stall of that CPU as the loop does.
  int cpu = -1;
  // Sleep until this long before each deadline, then spin on the clock up to it (0: sleep
  // only). A few hundred us spin away the sleep's late wake-ups, which otherwise stretch the
  // p99 period well past 1 ms (docs/physics-choices.md, "Haptics"), at the price of that share
  // of a core.
  std::int64_t spin_ns = 0;
  std::size_t ring_capacity = 4096;     // ticks physics may fall behind before samples are lost
  double velocity_cutoff_hz = 200;      // first-order low-pass on the device velocity
  std::int64_t max_extrapolation_ns = 50'000'000;  // proxy extrapolated at most this far
  // A newly published ContactModel fades in over this long, the one before it fading out (the
  // contact force is the blend of both, each evaluated at the device's current position; when
  // that one was itself still fading in, the blend the last tick rendered: model_fade.hpp):
  // physics moves the tissue's half-spaces once per step, and rendered at once that step's
  // motion times the contact stiffness would be a jump of up to 0.65 N within a tick.
  // -1: over the interval between the last two models (what the physics step takes), or the
  // time an interrupted fade had left if longer, at most max_blend_ns; 0: a new model takes
  // effect on the next tick as it is.
  std::int64_t blend_ns = -1;
  std::int64_t max_blend_ns = 50'000'000;
  // The energy observer and the damper that keeps the device from receiving net energy
  // (haptics/passivity.hpp, after Hannaford & Ryu 2002).
  PassivityParameters passivity{};
};

struct TickSample {
  std::uint64_t tick = 0;
  std::int64_t time_ns = 0;  // loop clock (CLOCK_MONOTONIC, or the simulated time given to tick())
  DevicePose pose{};          // position, orientation, buttons
  Vector3 velocity{};         // filtered device velocity, m/s
  Vector3 force{};            // written to the device, N (after the clamp)
  Vector3 contact_force{};    // its contact part before the clamp, N
  Vector3 cutting_force{};    // of which the cutting resistance (ContactModel::cutting), N
  Vector3 needle_force{};     // and the needle's (ContactModel::needle: axial friction, lateral grip), N
  DeviceState state = DeviceState::closed;
  bool clamped = false;       // the clamp reduced the force
  std::uint64_t contact_step = 0;  // ContactModel::step in effect
  Vector3 damper_force{};     // the passivity controller's part of force, N
  double device_energy = 0;   // J, net energy the loop has given the device up to this tick (passivity.hpp)
};

// The pieces, as free functions (the loop and the tests use the same ones).
// Throws std::invalid_argument for non-finite or negative values, or damping below K T / 2.
void validate(const CouplingParameters& coupling, double period_s);
double effective_damping(const CouplingParameters& coupling, double period_s);
Vector3 coupling_force(const CouplingParameters& coupling, double period_s, const Vector3& device_position,
                       const Vector3& device_velocity, const Vector3& proxy_position, const Vector3& proxy_velocity);
// Scales force down to |force| <= max_force, keeping its direction; a non-finite force becomes 0.
Vector3 clamp_force(const Vector3& force, double max_force, bool* clamped = nullptr);

// What the kernel says of the loop thread over its last run (getrusage(RUSAGE_THREAD) at its
// start and end): page faults it took and the times it was switched out while runnable. With
// none, each long period was the wake-up from the wait coming late, not the tick.
struct LoopThreadUsage {
  long minor_faults = 0, major_faults = 0;
  long involuntary_switches = 0;  // preempted while runnable
  long voluntary_switches = 0;    // the waits (one per tick that slept)
  bool measured = false;          // false until a run() has ended
};

class HapticLoop {
 public:
  // Validates the config against the device's limits (std::invalid_argument). The device and
  // the channel must outlive the loop. Allocates the ring here, never afterwards.
  HapticLoop(Device& device, ContactChannel& contacts, HapticLoopConfig config = {});
  ~HapticLoop();  // stop()
  HapticLoop(const HapticLoop&) = delete;
  HapticLoop& operator=(const HapticLoop&) = delete;

  void start();  // starts the thread; std::logic_error if running
  void stop();   // joins it; the device gets a zero force
  bool running() const { return thread_.joinable(); }
  bool realtime() const { return realtime_.load(std::memory_order_acquire); }
  // The CPU the thread was pinned to (HapticLoopConfig::cpu), or -1: not asked, refused, or
  // not started yet.
  int cpu() const { return cpu_.load(std::memory_order_acquire); }

  // One tick at time now_ns, on the caller's thread; only while the thread is not running
  // (std::logic_error otherwise). Headless replay and tests drive the loop this way.
  TickSample tick(std::int64_t now_ns);

  SpscRing<TickSample>& samples() { return ring_; }
  std::uint64_t ring_overflows() const { return overflows_.load(std::memory_order_relaxed); }
  TickSample latest() const { return latest_.load(); }
  std::uint64_t ticks() const { return ticks_.load(std::memory_order_acquire); }
  PeriodStatistics period_statistics() const { return periods_.summary(); }
  std::vector<LongPeriod> long_periods() const { return periods_.long_periods(); }
  LoopThreadUsage thread_usage() const { return usage_.load(); }  // after stop()
  std::uint64_t nonfinite_forces() const { return nonfinite_.load(std::memory_order_relaxed); }
  double period_s() const { return period_s_; }
  double coupling_damping() const { return damping_; }
  // The energy balance so far (passivity.hpp); any thread.
  PassivityFigures passivity() const { return passivity_figures_.load(); }
  const PassivityParameters& passivity_parameters() const { return config_.passivity; }

 private:
  TickSample step(std::int64_t now_ns);
  void run();

  Device& device_;
  ContactChannel& contacts_;
  HapticLoopConfig config_;
  double period_s_;
  std::int64_t period_ns_;
  double damping_;
  DeviceLimits limits_;

  // Loop-thread state.
  // The model in effect (copied from the channel when its step changes) and the ones it fades
  // in over (model_fade.hpp).
  ModelFade fade_;
  CuttingProxy cutting_proxy_;  // the crack front the hand pushes against (cutting_proxy.hpp)
  NeedleProxy needle_proxy_;    // the needle's friction anchor (needle_proxy.hpp)
  bool has_previous_ = false;
  Vector3 previous_position_{};
  std::int64_t previous_time_ns_ = 0;
  Vector3 velocity_{};
  bool velocity_primed_ = false;
  PassivityController passivity_;

  SpscRing<TickSample> ring_;
  Seqlock<TickSample> latest_;
  Seqlock<PassivityFigures> passivity_figures_;
  Seqlock<LoopThreadUsage> usage_;
  PeriodHistogram periods_;
  std::atomic<std::uint64_t> ticks_{0}, overflows_{0}, nonfinite_{0};
  std::atomic<bool> stop_{false}, realtime_{false};
  std::atomic<int> cpu_{-1};
  std::thread thread_;
};

// Waits until the absolute CLOCK_MONOTONIC time deadline_ns: clock_nanosleep(TIMER_ABSTIME) to
// deadline - spin_ns, then spins on clock_gettime. Shared by the loop and the baseline below.
void wait_until(std::int64_t deadline_ns, std::int64_t spin_ns);

// The baseline the issue asks for: a loop that does nothing but wait for the same deadlines
// (same rate, spin and priority settings), run on its own thread for duration_ns, in this
// process; its periods say what this machine allows.
PeriodStatistics measure_bare_loop(const HapticLoopConfig& config, std::int64_t duration_ns);
// The same into `histogram` (its long periods too): run on another thread beside a live loop,
// it tells which of the loop's long periods the host caused (long_periods_not_in). Returns the
// CPU it was pinned to (config.cpu), or -1.
int measure_bare_loop(const HapticLoopConfig& config, std::int64_t duration_ns, PeriodHistogram& histogram);

}  // namespace incise::haptics
