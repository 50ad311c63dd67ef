// The device the window drives from mouse and keyboard (issue 5: the blade follows the cursor
// on a plane, scroll for depth, a key or button to engage). The window thread calls
// set_pose(); the haptic thread reads it through a Seqlock, so the hot path takes no lock and
// the window never waits. Positions are clamped into the workspace. The forces written are
// kept for the window to show (last_force()). Always `ok` while open: there is no link to lose.
#pragma once

#include "haptics/device.hpp"
#include "haptics/seqlock.hpp"

namespace incise::haptics {

class VirtualDevice final : public Device {
 public:
  explicit VirtualDevice(const DeviceLimits& limits = {});

  // Any one thread (the window's). Throws std::invalid_argument on a non-finite position or
  // orientation or a quaternion that is not unit within kUnitQuaternionTolerance (it is
  // normalised when within). Returns the pose stored (after clamping).
  DevicePose set_pose(const DevicePose& pose);
  Vector3 last_force() const { return force_.load(); }

  std::string_view name() const override { return "virtual"; }
  void open() override;
  void close() override;
  DevicePose read_pose() override;
  DeviceState state() const override;
  void write_force(const Vector3& force) override;
  DeviceLimits limits() const override { return limits_; }

 private:
  DeviceLimits limits_;
  Seqlock<DevicePose> pose_;
  Seqlock<Vector3> force_;
  DevicePose last_read_{};
  std::atomic<bool> open_{false};
};

}  // namespace incise::haptics
