// One abstract haptic device (after CHAI3D's cGenericHapticDevice): adding a device is adding
// a class. The devices: VirtualDevice (virtual_device.hpp, set by the window from mouse and
// keyboard), ReplayDevice (replay_device.hpp, plays timestamped samples), UdpDevice
// (udp_device.hpp, a bridge process speaking docs/haptics-protocol.md). The 1 kHz loop that
// drives one is haptic_loop.hpp.
//
// Threading: read_pose(), state() and write_force() are called by the haptic thread only,
// once per tick, and must never block, allocate or take a lock. open() and close() are called
// by the owner (the engine) while no loop runs. limits() is constant between open and close.
#pragma once

#include <array>
#include <cmath>
#include <cstdint>
#include <stdexcept>
#include <string>
#include <string_view>

namespace incise::haptics {

using Vector3 = std::array<double, 3>;
using Quaternion = std::array<double, 4>;  // w, x, y, z

struct DevicePose {
  Vector3 position{};                 // m, world frame
  Quaternion orientation{1, 0, 0, 0};  // unit quaternion w, x, y, z
  std::uint32_t buttons = 0;           // bit 0: tool engaged
};

inline constexpr std::uint32_t kButtonEngage = 1u << 0;

struct DeviceLimits {
  Vector3 workspace_min{-0.1, -0.1, -0.1}, workspace_max{0.1, 0.1, 0.1};  // m
  double max_force = 3.0;                                                 // N, magnitude
};

// ok: the pose is current and forces are rendered. lost: no valid input for the device's
// timeout (udp: 50 ms); the pose is the last good one and any force written is replaced by
// zero until input resumes. closed: before open() or after close().
enum class DeviceState : std::uint8_t { closed = 0, ok = 1, lost = 2 };

inline const char* to_string(DeviceState s) {
  switch (s) {
    case DeviceState::closed: return "closed";
    case DeviceState::ok: return "ok";
    case DeviceState::lost: return "lost";
  }
  return "?";
}

class Device {
 public:
  virtual ~Device() = default;
  virtual std::string_view name() const = 0;
  virtual void open() = 0;   // throws std::runtime_error (with the reason) when it cannot
  virtual void close() = 0;  // idempotent
  // The newest pose; also refreshes state() (the udp device drains its socket here).
  virtual DevicePose read_pose() = 0;
  virtual DeviceState state() const = 0;
  // Force on the user's hand, N, world frame; the caller has clamped it to limits().max_force.
  virtual void write_force(const Vector3& force) = 0;
  virtual DeviceLimits limits() const = 0;
};

// Validation shared by the devices and the loop: std::invalid_argument naming what and where.
inline void require_finite(double value, const std::string& what) {
  if (!std::isfinite(value)) throw std::invalid_argument(what + " is not finite (" + std::to_string(value) + ")");
}
void require_finite_pose(const DevicePose& pose, const std::string& where);  // and unit quaternion
void validate_limits(const DeviceLimits& limits, const std::string& where);

// Quaternion helpers: |q| and q / |q|.
double quaternion_norm(const Quaternion& q);
inline constexpr double kUnitQuaternionTolerance = 1e-3;  // accepted | |q| - 1 |

}  // namespace incise::haptics
