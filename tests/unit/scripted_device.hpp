// A haptic device the test drives: it reads the pose and the state the test set, and keeps the
// last force written to it.
#pragma once

#include "haptics/device.hpp"

#include <string_view>

namespace incise::testing {

class ScriptedDevice final : public haptics::Device {
 public:
  haptics::DevicePose pose;
  haptics::DeviceState current = haptics::DeviceState::ok;
  haptics::Vector3 written{};
  std::string_view name() const override { return "scripted"; }
  void open() override {}
  void close() override {}
  haptics::DevicePose read_pose() override { return pose; }
  haptics::DeviceState state() const override { return current; }
  void write_force(const haptics::Vector3& f) override { written = f; }
  haptics::DeviceLimits limits() const override { return {}; }  // max_force 3 N
};

}  // namespace incise::testing
