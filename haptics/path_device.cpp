#include "haptics/path_device.hpp"

#include <algorithm>
#include <stdexcept>

namespace incise::haptics {

PathDevice::PathDevice(Path path, Clock clock, const DeviceLimits& limits)
    : path_(std::move(path)), clock_(std::move(clock)), limits_(limits) {
  if (!path_) throw std::invalid_argument("path device: no path");
  if (!clock_) throw std::invalid_argument("path device: no clock");
  validate_limits(limits_, "path device limits");
}

void PathDevice::start_at(std::int64_t t0_ns) { t0_ns_.store(t0_ns, std::memory_order_release); }

void PathDevice::open() { open_.store(true, std::memory_order_release); }
void PathDevice::close() {
  open_.store(false, std::memory_order_release);
  force_.store(Vector3{});
}

DevicePose PathDevice::read_pose() {
  const std::int64_t t0 = t0_ns_.load(std::memory_order_acquire);
  const std::int64_t since = t0 == kNotStarted ? 0 : std::max<std::int64_t>(0, clock_() - t0);
  DevicePose pose = path_(1e-9 * static_cast<double>(since));
  for (int i = 0; i < 3; ++i)
    pose.position[i] = std::clamp(pose.position[i], limits_.workspace_min[i], limits_.workspace_max[i]);
  return pose;
}

DeviceState PathDevice::state() const {
  return open_.load(std::memory_order_acquire) ? DeviceState::ok : DeviceState::closed;
}

void PathDevice::write_force(const Vector3& force) { force_.store(state() == DeviceState::ok ? force : Vector3{}); }

}  // namespace incise::haptics
