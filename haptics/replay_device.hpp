// Plays recorded samples as a device: the pose at time t is the linear interpolation by time
// of the two samples around t (positions linearly, orientations by normalised linear
// interpolation on the shorter arc, buttons held from the earlier sample). Before the first
// sample it holds the first, after the last the last (and finished() turns true).
//
// Time: open() notes the clock; the playback time is first_sample_time + (clock - open time),
// so with a ManualClock (or simulated time in headless replay) the playback is deterministic.
// Takes plain structs: the engine converts its trajectory records (engine/trajectory.hpp)
// into TimedPose; nothing here depends on engine/.
#pragma once

#include <vector>

#include "haptics/clock.hpp"
#include "haptics/device.hpp"
#include "haptics/seqlock.hpp"

namespace incise::haptics {

struct TimedPose {
  double time_s = 0;
  DevicePose pose;
};

class ReplayDevice final : public Device {
 public:
  // Throws std::invalid_argument when samples is empty, a time or pose is not finite (naming
  // the index), a quaternion is not unit, or times are not strictly increasing.
  explicit ReplayDevice(std::vector<TimedPose> samples, const DeviceLimits& limits = {},
                        Clock clock = monotonic_clock());

  // The interpolated pose at playback time t (seconds, the samples' own time base).
  DevicePose pose_at(double time_s) const;
  double start_time() const { return samples_.front().time_s; }
  double end_time() const { return samples_.back().time_s; }
  bool finished() const { return finished_.load(std::memory_order_acquire); }
  Vector3 last_force() const { return last_force_.load(); }  // the last write, any thread

  std::string_view name() const override { return "replay"; }
  void open() override;
  void close() override;
  DevicePose read_pose() override;
  DeviceState state() const override { return open_ ? DeviceState::ok : DeviceState::closed; }
  void write_force(const Vector3& force) override { last_force_.store(force); }
  DeviceLimits limits() const override { return limits_; }

 private:
  std::vector<TimedPose> samples_;
  DeviceLimits limits_;
  Clock clock_;
  std::int64_t open_time_ns_ = 0;
  std::size_t cursor_ = 0;  // samples_[cursor_].time_s <= last playback time (hot path search hint)
  bool open_ = false;
  std::atomic<bool> finished_{false};
  Seqlock<Vector3> last_force_;  // no actuator: kept for whoever shows it
};

}  // namespace incise::haptics
