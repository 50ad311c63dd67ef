#include "haptics/virtual_device.hpp"

#include <algorithm>

namespace incise::haptics {

VirtualDevice::VirtualDevice(const DeviceLimits& limits) : limits_(limits) {
  validate_limits(limits_, "virtual device limits");
  DevicePose centre;
  for (int i = 0; i < 3; ++i) centre.position[i] = 0.5 * (limits_.workspace_min[i] + limits_.workspace_max[i]);
  pose_.store(centre);
  last_read_ = centre;
}

DevicePose VirtualDevice::set_pose(const DevicePose& pose) {
  require_finite_pose(pose, "virtual device pose");
  DevicePose stored = pose;
  const double n = quaternion_norm(pose.orientation);
  for (double& q : stored.orientation) q /= n;
  for (int i = 0; i < 3; ++i)
    stored.position[i] = std::clamp(pose.position[i], limits_.workspace_min[i], limits_.workspace_max[i]);
  pose_.store(stored);
  return stored;
}

void VirtualDevice::open() { open_.store(true, std::memory_order_release); }
void VirtualDevice::close() {
  open_.store(false, std::memory_order_release);
  force_.store(Vector3{});
}

DevicePose VirtualDevice::read_pose() {
  // A read that keeps overlapping writes (it would take a window thread writing in a tight
  // loop) keeps the previous pose rather than spin: the tick is never held up.
  pose_.try_load(last_read_);
  return last_read_;
}

DeviceState VirtualDevice::state() const {
  return open_.load(std::memory_order_acquire) ? DeviceState::ok : DeviceState::closed;
}

void VirtualDevice::write_force(const Vector3& force) { force_.store(state() == DeviceState::ok ? force : Vector3{}); }

}  // namespace incise::haptics
