// The needle's force through the haptic loop (issue 30; engine/needle_haptics.cpp,
// haptics/needle_proxy.hpp), on the EFG lobe of assets/scenes/needle_lobe.json driven by a
// scripted virtual device on the simulated clock: the hand pushing the needle in feels the
// tissue resist along the shaft (and nothing before the tip reaches it), held in the tissue and
// moved 1 mm across the shaft it is pulled back, pulled out it feels the friction the other
// way; the force changes by a bounded amount from tick to tick, through every publication, and
// the passivity observer never books energy given to the hand.
#include "engine/haptic_session.hpp"
#include "engine/scene.hpp"
#include "engine/world.hpp"
#include "haptics/virtual_device.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>

using namespace incise::engine;
namespace haptics = incise::haptics;

namespace {

const std::filesystem::path kScene = std::filesystem::path(INCISE_SOURCE_DIR) / "assets/scenes/needle_lobe.json";

// The scene's needle column, its tip from 6 mm above the lobe's top (z = 0.062) down at 20 mm/s
// to 12 mm below the top (0.9 s), held there; from 1.1 s 1 mm across along x (over 20 ms), back
// from 1.2 s, and drawn back from 1.3 s at 50 mm/s by 4 mm.
haptics::DevicePose hand(double t) {
  const auto ramp = [&](double from, double over) { return std::clamp((t - from) / over, 0.0, 1.0); };
  haptics::DevicePose pose;
  const double z = 0.068 - 0.018 * ramp(0, 0.9) + 0.004 * ramp(1.3, 0.08);
  pose.position = {0.0014 + 0.001 * (ramp(1.1, 0.02) - ramp(1.2, 0.02)), 0.0012, z};
  return pose;
}

}  // namespace

TEST(HapticNeedle, TheHandFeelsTheShaftResistedAlongAndHeldAcross) {
  const Scene scene = load_scene(kScene);
  haptics::VirtualDevice device;
  SessionOptions options;
  options.keep_ticks = true;
  options.script = [&](double t) { device.set_pose(hand(t)); };
  HapticSession session(scene, device, options);
  const auto steps = [&](double seconds) {
    for (int k = 0; k < static_cast<int>(std::lround(seconds / session.world().dt())); ++k) session.step();
  };
  steps(0.25);  // above the lobe: no force
  EXPECT_EQ(session.loop().latest().needle_force, (haptics::Vector3{0, 0, 0}));
  EXPECT_EQ(session.last_model().needle.stiffness, 0.0);
  steps(0.65);  // 12 mm in, still pushing
  const auto in = session.loop().latest();
  const haptics::NeedleResistance needle = session.last_model().needle;
  std::printf("pushing in at 12 mm: needle force (%.4f, %.4f, %.4f) N; model: insert %.4f N, retract %.4f N, "
              "stiffness %.1f N/m\n", in.needle_force[0], in.needle_force[1], in.needle_force[2], needle.insert_force,
              needle.retract_force, needle.stiffness);
  EXPECT_GT(needle.stiffness, 0.0);
  EXPECT_GT(needle.insert_force, needle.retract_force);
  EXPECT_GT(needle.retract_force, 0.0);
  EXPECT_GT(in.needle_force[2], 0.5 * needle.insert_force);  // up, against the insertion
  steps(0.2);  // held at 12 mm
  const double held_x = session.loop().latest().needle_force[0];
  steps(0.02);  // 1 mm across
  const auto across = session.loop().latest();
  std::printf("moved 1 mm across: needle force x %.4f N (held: %.4f N)\n", across.needle_force[0], held_x);
  EXPECT_LT(across.needle_force[0], held_x - 0.1 * session.last_model().needle.stiffness * 0.001);
  steps(0.18);  // back onto the line, then drawn back 4 mm
  steps(0.08);
  const auto out = session.loop().latest();
  std::printf("pulled out: needle force z %.4f N (retract level %.4f N)\n", out.needle_force[2],
              session.last_model().needle.retract_force);
  EXPECT_LT(out.needle_force[2], 0.0);  // down, against the retraction
  EXPECT_LE(-out.needle_force[2], session.last_model().needle.retract_force * (1 + 1e-9) + 1e-9);
  session.stop();

  // Every tick: the change of the needle's force, and the observer's energy.
  double jump = 0, energy = -1e300;
  std::size_t worst = 0;
  const auto& ticks = session.ticks();
  for (std::size_t i = 1; i < ticks.size(); ++i) {
    double change = 0;
    for (int c = 0; c < 3; ++c) change += std::pow(ticks[i].needle_force[c] - ticks[i - 1].needle_force[c], 2);
    if (std::sqrt(change) > jump) jump = std::sqrt(change), worst = i;
    energy = std::max(energy, ticks[i].device_energy);
  }
  std::printf("%zu ticks: largest change of the needle force %.4f N per tick (at %.3f s, model %llu), device "
              "energy at most %.3g J\n", ticks.size(), jump, 1e-9 * static_cast<double>(ticks[worst].time_ns),
              static_cast<unsigned long long>(ticks[worst].contact_step), energy);
  EXPECT_LT(jump, 0.05);
  EXPECT_LE(energy, 1e-9);
}
