#include "haptics/haptic_loop.hpp"

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <numbers>
#include <pthread.h>
#include <sched.h>
#include <stdexcept>
#include <string>
#include <sys/resource.h>
#include <time.h>

#include "haptics/clock.hpp"

namespace incise::haptics {

void validate(const CouplingParameters& coupling, double period_s) {
  require_finite(coupling.stiffness, "coupling.stiffness");
  require_finite(coupling.damping, "coupling.damping");
  if (coupling.stiffness < 0) throw std::invalid_argument("coupling.stiffness is negative");
  if (coupling.damping >= 0 && coupling.damping < 0.5 * coupling.stiffness * period_s)
    throw std::invalid_argument("coupling.damping " + std::to_string(coupling.damping) +
                                " N s/m is below K T / 2 = " + std::to_string(0.5 * coupling.stiffness * period_s) +
                                " N s/m (Colgate's passivity bound for a spring sampled at period T)");
}

double effective_damping(const CouplingParameters& coupling, double period_s) {
  return coupling.damping < 0 ? coupling.stiffness * period_s : coupling.damping;
}

Vector3 coupling_force(const CouplingParameters& coupling, double period_s, const Vector3& x, const Vector3& v,
                       const Vector3& proxy_x, const Vector3& proxy_v) {
  const double b = effective_damping(coupling, period_s);
  Vector3 f;
  for (int i = 0; i < 3; ++i) f[i] = coupling.stiffness * (proxy_x[i] - x[i]) + b * (proxy_v[i] - v[i]);
  return f;
}

Vector3 clamp_force(const Vector3& force, double max_force, bool* clamped) {
  if (clamped) *clamped = false;
  if (!std::isfinite(force[0]) || !std::isfinite(force[1]) || !std::isfinite(force[2])) {
    if (clamped) *clamped = true;
    return Vector3{};
  }
  const double magnitude = std::sqrt(force[0] * force[0] + force[1] * force[1] + force[2] * force[2]);
  if (magnitude <= max_force) return force;
  if (clamped) *clamped = true;
  const double scale = max_force / magnitude;
  return {force[0] * scale, force[1] * scale, force[2] * scale};
}

HapticLoop::HapticLoop(Device& device, ContactChannel& contacts, HapticLoopConfig config)
    : device_(device),
      contacts_(contacts),
      config_(config),
      passivity_(config.passivity),
      ring_(config.ring_capacity == 0 ? 1 : config.ring_capacity) {
  require_finite(config_.rate_hz, "haptic loop rate_hz");
  if (!(config_.rate_hz >= 1 && config_.rate_hz <= 100'000))
    throw std::invalid_argument("haptic loop rate_hz " + std::to_string(config_.rate_hz) + " is outside [1, 100000]");
  if (config_.ring_capacity == 0) throw std::invalid_argument("haptic loop ring_capacity must be > 0");
  require_finite(config_.velocity_cutoff_hz, "haptic loop velocity_cutoff_hz");
  if (!(config_.velocity_cutoff_hz > 0)) throw std::invalid_argument("haptic loop velocity_cutoff_hz must be > 0");
  if (config_.spin_ns < 0 || config_.max_extrapolation_ns < 0)
    throw std::invalid_argument("haptic loop spin_ns and max_extrapolation_ns must be >= 0");
  if (config_.blend_ns < -1 || config_.max_blend_ns < 0)
    throw std::invalid_argument("haptic loop blend_ns must be >= -1 and max_blend_ns >= 0");
  period_s_ = 1.0 / config_.rate_hz;
  period_ns_ = static_cast<std::int64_t>(std::llround(1e9 / config_.rate_hz));
  validate(config_.coupling, period_s_);
  damping_ = effective_damping(config_.coupling, period_s_);
  limits_ = device_.limits();
  validate_limits(limits_, std::string(device_.name()) + " device limits");
}

HapticLoop::~HapticLoop() { stop(); }

TickSample HapticLoop::tick(std::int64_t now_ns) {
  if (running()) throw std::logic_error("HapticLoop::tick while the loop thread runs");
  return step(now_ns);
}

TickSample HapticLoop::step(std::int64_t now_ns) {
  TickSample s;
  s.tick = ticks_.load(std::memory_order_relaxed);
  s.time_ns = now_ns;
  s.pose = device_.read_pose();
  s.state = device_.state();
  const Vector3& x = s.pose.position;

  // Device velocity: backward difference over the measured interval, low-passed (a bare
  // difference of a quantised encoder would make the damper buzz).
  if (has_previous_ && now_ns > previous_time_ns_) {
    const double dt = 1e-9 * static_cast<double>(now_ns - previous_time_ns_);
    Vector3 raw;
    for (int i = 0; i < 3; ++i) raw[i] = (x[i] - previous_position_[i]) / dt;
    const double alpha = velocity_primed_ ? dt / (dt + 1.0 / (2 * std::numbers::pi * config_.velocity_cutoff_hz)) : 1.0;
    for (int i = 0; i < 3; ++i) velocity_[i] += alpha * (raw[i] - velocity_[i]);
    velocity_primed_ = true;
  }
  has_previous_ = true;
  previous_position_ = x;
  previous_time_ns_ = now_ns;
  s.velocity = velocity_;

  // A new model fades in, over blend_ns (or the last interval between models), from what the
  // last tick rendered (model_fade.hpp): each model is evaluated at the device's position now.
  const ContactModel& latest = contacts_.read();
  if (!fade_.has_model() || latest.step != fade_.newest().step)
    fade_.publish(latest, now_ns, config_.blend_ns, config_.max_blend_ns);
  ModelFade::Weights blend;
  const std::span<const WeightedModel> models(blend.data(), static_cast<std::size_t>(fade_.weights(now_ns, period_ns_, blend)));
  const ContactModel& model = fade_.newest();
  s.contact_step = model.step;
  Vector3 total{};
  if (model.has_proxy) {
    std::int64_t ahead = now_ns - model.time_ns;
    if (ahead < 0) ahead = 0;
    if (ahead > config_.max_extrapolation_ns) ahead = config_.max_extrapolation_ns;
    Vector3 proxy;
    for (int i = 0; i < 3; ++i) proxy[i] = model.proxy_position[i] + 1e-9 * static_cast<double>(ahead) * model.proxy_velocity[i];
    total = coupling_force(config_.coupling, period_s_, x, velocity_, proxy, model.proxy_velocity);
  }
  s.contact_force = contact_force(model, x, velocity_, period_s_);
  if (models.size() > 1) {
    for (int i = 0; i < 3; ++i) s.contact_force[i] *= models[0].weight;
    for (const WeightedModel& m : models.subspan(1)) {
      const Vector3 before = contact_force(*m.model, x, velocity_, period_s_);
      for (int i = 0; i < 3; ++i) s.contact_force[i] += m.weight * before[i];
    }
  }
  const BlendedCutting cutting = blend_cutting(models, x);
  s.cutting_force = cutting_proxy_.tick(cutting.term, cutting.level, x, period_s_);
  for (int i = 0; i < 3; ++i) s.contact_force[i] += s.cutting_force[i];
  s.needle_force = needle_proxy_.tick(models, x);
  for (int i = 0; i < 3; ++i) s.contact_force[i] += s.needle_force[i];
  for (int i = 0; i < 3; ++i) total[i] += s.contact_force[i];

  if (!std::isfinite(total[0]) || !std::isfinite(total[1]) || !std::isfinite(total[2]))
    nonfinite_.fetch_add(1, std::memory_order_relaxed);
  const bool render = s.state == DeviceState::ok;
  if (!render) total = Vector3{};
  const Vector3 rendered = clamp_force(total, limits_.max_force, &s.clamped);
  s.force = passivity_.tick(x, velocity_, rendered, period_s_, limits_.max_force, render);
  s.damper_force = passivity_.damper_force();
  s.device_energy = passivity_.energy();
  device_.write_force(s.force);
  passivity_figures_.store(passivity_.figures());

  if (!ring_.try_push(s)) overflows_.fetch_add(1, std::memory_order_relaxed);
  latest_.store(s);
  ticks_.fetch_add(1, std::memory_order_release);
  return s;
}

void wait_until(std::int64_t deadline_ns, std::int64_t spin_ns) {
  const std::int64_t sleep_to = deadline_ns - spin_ns;
  timespec target{static_cast<time_t>(sleep_to / 1'000'000'000), static_cast<long>(sleep_to % 1'000'000'000)};
  while (clock_nanosleep(CLOCK_MONOTONIC, TIMER_ABSTIME, &target, nullptr) == EINTR) {
  }
  if (spin_ns > 0)
    while (monotonic_now_ns() < deadline_ns) {
    }
}

namespace {

bool try_realtime(const HapticLoopConfig& config) {
  if (!config.realtime_priority) return false;
  sched_param param{};
  param.sched_priority = config.realtime_priority_level;
  // EPERM without CAP_SYS_NICE / rtprio: quietly stay at normal priority.
  return pthread_setschedparam(pthread_self(), SCHED_FIFO, &param) == 0;
}

// Pins the calling thread to config.cpu; the CPU, or -1 when not asked or refused (a CPU
// outside the process's set, or a container that forbids it).
int try_pin(const HapticLoopConfig& config) {
  if (config.cpu < 0 || config.cpu >= CPU_SETSIZE) return -1;
  cpu_set_t set;
  CPU_ZERO(&set);
  CPU_SET(config.cpu, &set);
  return pthread_setaffinity_np(pthread_self(), sizeof set, &set) == 0 ? config.cpu : -1;
}

// Next deadline after a tick: one period on, or, when the tick started more than a period
// late (the host preempted us), the first deadline still ahead; the skipped ones are counted,
// not made up in a burst.
std::int64_t next_deadline(std::int64_t deadline, std::int64_t period, std::int64_t now, PeriodHistogram& h) {
  deadline += period;
  if (deadline <= now) {
    const std::int64_t behind = (now - deadline) / period + 1;
    h.record_missed(static_cast<std::uint64_t>(behind));
    deadline += behind * period;
  }
  return deadline;
}

// A period from the tick started at previous_start (whose work ended at worked_until) to the
// tick starting at start, due at deadline.
void record_period(PeriodHistogram& h, std::int64_t previous_start, std::int64_t worked_until, std::int64_t deadline,
                   std::int64_t start) {
  if (previous_start == 0) return;
  const std::int64_t period = start - previous_start;
  h.record(period);
  if (period > 2'000'000) h.record_long({start, period, start - deadline, worked_until - previous_start});
}

}  // namespace

void HapticLoop::start() {
  if (running()) throw std::logic_error("HapticLoop::start: already running");
  stop_.store(false, std::memory_order_release);
  periods_.reset();
  thread_ = std::thread([this] { run(); });
}

void HapticLoop::stop() {
  if (!running()) return;
  stop_.store(true, std::memory_order_release);
  thread_.join();
  device_.write_force(Vector3{});
}

void HapticLoop::run() {
  cpu_.store(try_pin(config_), std::memory_order_release);
  realtime_.store(try_realtime(config_), std::memory_order_release);
  rusage before{}, after{};
  const bool measured = getrusage(RUSAGE_THREAD, &before) == 0;
  std::int64_t deadline = monotonic_now_ns() + period_ns_;
  std::int64_t previous_start = 0, worked_until = 0;
  while (!stop_.load(std::memory_order_acquire)) {
    wait_until(deadline, config_.spin_ns);
    const std::int64_t start = monotonic_now_ns();
    record_period(periods_, previous_start, worked_until, deadline, start);
    previous_start = start;
    step(start);
    worked_until = monotonic_now_ns();
    deadline = next_deadline(deadline, period_ns_, worked_until, periods_);
  }
  if (measured && getrusage(RUSAGE_THREAD, &after) == 0)
    usage_.store({after.ru_minflt - before.ru_minflt, after.ru_majflt - before.ru_majflt,
                  after.ru_nivcsw - before.ru_nivcsw, after.ru_nvcsw - before.ru_nvcsw, true});
}

int measure_bare_loop(const HapticLoopConfig& config, std::int64_t duration_ns, PeriodHistogram& histogram) {
  int cpu = -1;
  std::thread bare([&] {
    cpu = try_pin(config);
    try_realtime(config);
    const std::int64_t period = static_cast<std::int64_t>(std::llround(1e9 / config.rate_hz));
    const std::int64_t end = monotonic_now_ns() + duration_ns;
    std::int64_t deadline = monotonic_now_ns() + period;
    std::int64_t previous_start = 0, worked_until = 0;
    for (;;) {
      wait_until(deadline, config.spin_ns);
      const std::int64_t start = monotonic_now_ns();
      if (start >= end) break;
      record_period(histogram, previous_start, worked_until, deadline, start);
      previous_start = start;
      worked_until = monotonic_now_ns();
      deadline = next_deadline(deadline, period, worked_until, histogram);
    }
  });
  bare.join();
  return cpu;
}

PeriodStatistics measure_bare_loop(const HapticLoopConfig& config, std::int64_t duration_ns) {
  PeriodHistogram histogram;
  measure_bare_loop(config, duration_ns, histogram);
  return histogram.summary();
}

}  // namespace incise::haptics
