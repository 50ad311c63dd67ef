// The needle's term of the haptic loop (haptics/needle_proxy.hpp): along the shaft a friction
// spring that slips at the insertion level pushing in and at the friction level pulling out,
// across it a spring back onto the tissue's line; a stroke in and out gives the hand no energy
// and changes the force by at most k |dx| a tick; in the loop, a model whose levels drop (the
// puncture given way) fades in, and the passivity observer's energy stays at or below zero.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <string>

#include "haptics/haptic_loop.hpp"
#include "haptics/needle_proxy.hpp"
#include "tests/unit/scripted_device.hpp"

using namespace incise::haptics;
using incise::testing::ScriptedDevice;

namespace {

constexpr std::int64_t kMs = 1'000'000;

// A needle going down (-z) through the line x = y = 0: pushing in resisted at 0.3 N, pulling out
// at 0.1 N, 400 N/m.
ContactModel needle_model(double insert = 0.3, double retract = 0.1) {
  ContactModel m;
  m.needle.axis = {0, 0, -1};
  m.needle.line = {0, 0, 0};
  m.needle.insert_force = insert;
  m.needle.retract_force = retract;
  m.needle.stiffness = 400;
  return m;
}

}  // namespace

TEST(HapticsNeedle, TheShaftSlipsAtTheInsertionLevelInAndTheFrictionOutAndIsHeldAcross) {
  const ContactModel m = needle_model();
  NeedleProxy proxy;
  Vector3 f = proxy.tick(m, nullptr, 1.0, {0, 0, 0});
  EXPECT_EQ(f, (Vector3{0, 0, 0}));  // enters unloaded where the hand is
  f = proxy.tick(m, nullptr, 1.0, {0, 0, -0.0005});  // 0.5 mm in: the spring, 0.2 N back up
  EXPECT_NEAR(f[2], 0.2, 1e-12);
  f = proxy.tick(m, nullptr, 1.0, {0, 0, -0.005});  // 5 mm in: slipping at the insertion level
  EXPECT_NEAR(f[2], 0.3, 1e-12);
  f = proxy.tick(m, nullptr, 1.0, {0, 0, -0.0045});  // back 0.5 mm: the spring unloads, then pulls
  EXPECT_NEAR(f[2], 0.1, 1e-12);
  f = proxy.tick(m, nullptr, 1.0, {0, 0, -0.003});  // pulling out: friction only, downwards
  EXPECT_NEAR(f[2], -0.1, 1e-12);
  // 1 mm across the line: 0.4 N back towards it, the axial spring unchanged.
  f = proxy.tick(m, nullptr, 1.0, {0.001, 0, -0.003});
  EXPECT_NEAR(f[0], -0.4, 1e-12);
  EXPECT_NEAR(f[2], -0.1, 1e-12);
  EXPECT_NEAR(needle_lateral_force(m.needle, {0, 0.002, 0.7})[1], -0.8, 1e-12);
  // Out of the tissue: nothing, and the next entry starts unloaded.
  ContactModel out = m;
  out.needle.stiffness = 0;
  EXPECT_EQ(proxy.tick(out, nullptr, 1.0, {0.001, 0, -0.003}), (Vector3{0, 0, 0}));
  EXPECT_FALSE(proxy.engaged());
  EXPECT_EQ(proxy.tick(m, nullptr, 1.0, {0, 0, -0.01}), (Vector3{0, 0, 0}));
}

// In 10 mm and out again at 10 mm/s, twice, with a 0.5 mm sideways wobble, at 1 kHz: the force
// changes by at most k |dx| a tick and the hand gets no energy back over the closed path.
TEST(HapticsNeedle, AStrokeInAndOutFeelsNoJumpAndGetsNoEnergyBack) {
  const ContactModel m = needle_model();
  NeedleProxy proxy;
  const double dt = 1e-3, speed = 0.01;
  Vector3 x{}, previous{};
  double work = 0, jump = 0, most_in = 0, most_out = 0;
  for (int tick = 0; tick <= 4000; ++tick) {
    const double t = tick * dt, phase = std::fmod(t, 2.0);
    const Vector3 next{0.0005 * std::sin(2 * M_PI * t), 0, -(phase < 1 ? speed * phase : speed * (2 - phase))};
    const Vector3 f = proxy.tick(m, nullptr, 1.0, next);
    for (int i = 0; i < 3; ++i) work += f[i] * (next[i] - x[i]);
    double change = 0;
    for (int i = 0; i < 3; ++i) change += (f[i] - previous[i]) * (f[i] - previous[i]);
    double step = 0;
    for (int i = 0; i < 3; ++i) step += (next[i] - x[i]) * (next[i] - x[i]);
    if (tick > 0) jump = std::max(jump, std::sqrt(change) / std::sqrt(step));
    most_in = std::max(most_in, f[2]);
    most_out = std::min(most_out, f[2]);
    previous = f;
    x = next;
  }
  EXPECT_NEAR(most_in, 0.3, 1e-12);
  EXPECT_NEAR(most_out, -0.1, 1e-12);
  EXPECT_LE(jump, 400 * (1 + 1e-9));  // N/m: at most k |dx|
  EXPECT_LT(work, 0.0);  // friction takes; the lateral spring returns what it stored
  // Each slipping tick dissipates (F_in or F_out) times the slip: about 0.4 N x 20 mm a cycle.
  EXPECT_NEAR(work, -2 * (0.3 + 0.1) * 0.01, 2e-3);
}

// In the loop: the device pushed in at 10 cm/s while physics publishes every 10 ms, the
// puncture's 0.6 N giving way to 0.2 N at 50 ms; the new level fades in over the step (no drop
// of 0.4 N in a tick), the force stays at the level, and the passivity observer never books
// energy given to the hand.
TEST(HapticsNeedle, TheLoopFadesAPunctureGivingWayAndStaysPassive) {
  ScriptedDevice device;
  ContactModel model = needle_model(0.6, 0.1);
  model.step = 1;
  ContactChannel channel(model);
  HapticLoop loop(device, channel);
  double previous = 0, jump = 0, energy = 0;
  for (int k = 0; k < 200; ++k) {
    if (k % 10 == 0 && k > 0) {
      model.step = static_cast<std::uint64_t>(k / 10 + 1);
      if (k >= 50) model.needle.insert_force = 0.2;
      channel.write(model);
    }
    device.pose.position = {0.0002 * std::sin(0.05 * k), 0, -0.1 * k * 1e-3};
    const TickSample s = loop.tick(k * kMs);
    if (k > 0) jump = std::max(jump, std::abs(s.needle_force[2] - previous));
    previous = s.needle_force[2];
    energy = std::max(energy, s.device_energy);
    if (k == 45) {
      EXPECT_NEAR(s.needle_force[2], 0.6, 1e-3) << "the puncture's level";
    }
    if (k == 199) {
      EXPECT_NEAR(s.needle_force[2], 0.2, 1e-3) << "the insertion's level";
    }
  }
  EXPECT_LE(jump, 0.04 + 1e-9);  // k |dx| loading, and the drop of 0.4 N over the 10 ticks of the fade
  EXPECT_LE(energy, 1e-12);
}

TEST(HapticsNeedle, ValidationNamesTheBadField) {
  ContactModel m = needle_model();
  m.needle.axis = {0, 0, -0.5};
  try {
    validate(m);
    FAIL() << "a non-unit axis was accepted";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("ContactModel.needle.axis is not unit"), std::string::npos);
  }
  m = needle_model(-0.1);
  EXPECT_THROW(validate(m), std::invalid_argument);
  m.needle.insert_force = 0.3;
  m.needle.stiffness = 0;
  m.needle.axis = {0, 0, 0};  // out of the tissue: the axis is not used
  EXPECT_NO_THROW(validate(m));
}
