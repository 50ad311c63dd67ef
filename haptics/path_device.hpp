// A device whose pose is a function of time, evaluated when the loop reads it: a scripted hand
// (`incise bench haptics`) that moves as a real device does, which reports where it is at the
// moment it is read. A thread setting a VirtualDevice from the wall clock every few hundred
// microseconds instead moves the device in jumps whenever that thread wakes late, and the loop
// then renders the hand's jump (the cutting spring's k dx) as if it were its own.
//
// Threading: as Device (read_pose(), state(), write_force() on the haptic thread, never
// blocking, allocating or locking: the path is called through a std::function, which does not
// allocate). start_at() may be called from any thread while the loop runs.
#pragma once

#include "haptics/clock.hpp"
#include "haptics/device.hpp"
#include "haptics/seqlock.hpp"

#include <atomic>
#include <cstdint>
#include <functional>
#include <limits>

namespace incise::haptics {

class PathDevice final : public Device {
 public:
  using Path = std::function<DevicePose(double seconds)>;

  // The pose at `seconds` after the path's start; the position is clamped into the workspace.
  // std::invalid_argument when the path is empty or a limit is invalid.
  explicit PathDevice(Path path, Clock clock = monotonic_clock(), const DeviceLimits& limits = {});

  // The clock time (ns) the path's t = 0 is at. Until it is set the device reads path(0); a
  // read before the start reads path(0) too.
  void start_at(std::int64_t t0_ns);
  Vector3 last_force() const { return force_.load(); }

  std::string_view name() const override { return "path"; }
  void open() override;
  void close() override;
  DevicePose read_pose() override;
  DeviceState state() const override;
  void write_force(const Vector3& force) override;
  DeviceLimits limits() const override { return limits_; }

 private:
  static constexpr std::int64_t kNotStarted = std::numeric_limits<std::int64_t>::min();
  Path path_;
  Clock clock_;
  DeviceLimits limits_;
  Seqlock<Vector3> force_;
  std::atomic<std::int64_t> t0_ns_{kNotStarted};
  std::atomic<bool> open_{false};
};

}  // namespace incise::haptics
