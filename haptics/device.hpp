// One abstract haptic device (after CHAI3D's cGenericHapticDevice): adding a device is adding
// a class. The 1 kHz loop that drives it, and the virtual, replay and udp devices, come with
// issue 5; headless replay reads recorded samples directly (engine/trajectory.hpp).
#pragma once

#include <array>
#include <cstdint>

namespace incise::haptics {

struct DevicePose {
  std::array<double, 3> position{};           // m, world frame
  std::array<double, 4> orientation{1, 0, 0, 0};  // unit quaternion w, x, y, z
  std::uint32_t buttons = 0;                  // bit 0: tool engaged
};

struct DeviceLimits {
  std::array<double, 3> workspace_min{}, workspace_max{};  // m
  double max_force = 0;                                     // N
};

class Device {
 public:
  virtual ~Device() = default;
  virtual void open() = 0;
  virtual void close() = 0;
  virtual DevicePose read_pose() = 0;
  virtual void write_force(const std::array<double, 3>& force) = 0;
  virtual DeviceLimits limits() const = 0;
};

}  // namespace incise::haptics
