// The 1 kHz loop: the force it renders for a known ContactModel and pose (on its own thread,
// and on simulated time with the damping terms), the clamp, zero force when the device is
// lost, validation of non-finite input, and a printed (never asserted) period measurement
// beside a bare timing loop.
#include <gtest/gtest.h>

#include <chrono>
#include <cmath>
#include <cstdlib>
#include <limits>
#include <numbers>
#include <thread>
#include <vector>

#include "haptics/haptic_loop.hpp"
#include "haptics/model_fade.hpp"
#include "haptics/replay_device.hpp"
#include "haptics/virtual_device.hpp"
#include "tests/unit/scripted_device.hpp"

using namespace incise::haptics;
using incise::testing::ScriptedDevice;

namespace {

constexpr std::int64_t kMs = 1'000'000;

template <typename F>
std::string error_of(F&& f) {
  try {
    f();
  } catch (const std::invalid_argument& e) {
    return e.what();
  }
  return "(no error)";
}

// Tissue plane z = 0 (normal +z), probe of radius 2 mm, penalty 500 N/m in series with a
// compliance of 1 mm/N: k_eff = 1 / (1/500 + 0.001) = 333.33 N/m.
ContactModel known_model() {
  ContactModel m;
  m.count = 1;
  m.contacts[0].point = {0, 0, 0};
  m.contacts[0].normal = {0, 0, 1};
  m.contacts[0].reach = 0.002;
  m.contacts[0].stiffness = 500;
  m.contacts[0].compliance = 0.001;
  m.has_proxy = true;
  m.proxy_position = {0.002, 0, 0.001};
  m.step = 7;
  return m;
}

void expect_near(const Vector3& a, const Vector3& b, double tolerance, const std::string& what) {
  for (int i = 0; i < 3; ++i) EXPECT_NEAR(a[i], b[i], tolerance) << what << " [" << i << "]";
}

}  // namespace

TEST(HapticsCoupling, DampingBelowColgatesBoundAndNonFiniteValuesAreRefused) {
  const double T = 1e-3;
  EXPECT_NO_THROW(validate(CouplingParameters{300, 0.15}, T));  // exactly K T / 2
  EXPECT_EQ(error_of([&] { validate(CouplingParameters{300, 0.1}, T); }),
            "coupling.damping 0.100000 N s/m is below K T / 2 = 0.150000 N s/m (Colgate's passivity bound for a "
            "spring sampled at period T)");
  EXPECT_EQ(error_of([&] { validate(CouplingParameters{std::nan(""), -1}, T); }),
            "coupling.stiffness is not finite (nan)");
  EXPECT_DOUBLE_EQ(effective_damping(CouplingParameters{300, -1}, T), 0.3);  // default K T

  ScriptedDevice device;
  ContactChannel channel;
  HapticLoopConfig config;
  config.rate_hz = std::numeric_limits<double>::infinity();
  EXPECT_EQ(error_of([&] { HapticLoop loop(device, channel, config); }), "haptic loop rate_hz is not finite (inf)");
  config = {};
  config.coupling.damping = 0.01;
  EXPECT_NE(error_of([&] { HapticLoop loop(device, channel, config); }).find("below K T / 2"), std::string::npos);
}

TEST(HapticsContactModel, ValidationNamesTheBadField) {
  ContactModel m = known_model();
  EXPECT_NO_THROW(validate(m));
  m.contacts[0].point[2] = std::numeric_limits<double>::quiet_NaN();
  EXPECT_EQ(error_of([&] { validate(m); }), "ContactModel.contacts[0].point[2] is not finite (nan)");
  m = known_model();
  m.contacts[0].normal = {0, 0, 0.5};
  EXPECT_EQ(error_of([&] { validate(m); }), "ContactModel.contacts[0].normal is not unit (|n| = 0.500000)");
  m = known_model();
  m.contacts[0].stiffness = 0;
  EXPECT_NE(error_of([&] { validate(m); }).find("stiffness 0.000000 is not > 0"), std::string::npos);
  m = known_model();
  m.count = 17;
  EXPECT_NE(error_of([&] { validate(m); }).find("count 17 is outside [0, 16]"), std::string::npos);
  m = known_model();
  m.proxy_velocity[1] = -std::numeric_limits<double>::infinity();
  EXPECT_EQ(error_of([&] { validate(m); }), "ContactModel.proxy_velocity[1] is not finite (-inf)");
}

TEST(HapticsContactModel, ForceIsTheSeriesSpringAlongTheNormalAndNeverPulls) {
  const ContactModel m = known_model();
  const double k_eff = 1.0 / (1.0 / 500 + 0.001);
  expect_near(contact_force(m, {0, 0, 0.001}, {0, 0, 0}, 1e-3), {0, 0, k_eff * 0.001}, 1e-15, "1 mm deep");
  expect_near(contact_force(m, {0, 0, 0.0025}, {0, 0, 0}, 1e-3), {0, 0, 0}, 0, "out of contact");
  // Pressing in at 0.1 m/s adds the k_eff T damper; pulling out fast cannot make it pull.
  expect_near(contact_force(m, {0, 0, 0.001}, {0, 0, -0.1}, 1e-3), {0, 0, k_eff * 0.001 + k_eff * 1e-3 * 0.1}, 1e-15,
              "pressing");
  expect_near(contact_force(m, {0, 0, 0.0019}, {0, 0, 10}, 1e-3), {0, 0, 0}, 0, "leaving");
}

TEST(HapticsContactModel, ForceFadesOutsideTheDomainOfTheLinearisation) {
  ContactModel m = known_model();
  const double k_eff = 1.0 / (1.0 / 500 + 0.001);
  m.linearised_at = {0, 0, 0};
  m.valid_radius = 0.01;
  // Within half the radius: the full force; half way between R / 2 and R: half; beyond: none.
  expect_near(contact_force(m, {0.004, 0, 0.001}, {0, 0, 0}, 1e-3), {0, 0, k_eff * 0.001}, 1e-15, "inside");
  expect_near(contact_force(m, {0.0075, 0, 0}, {0, 0, 0}, 1e-3), {0, 0, 0.5 * k_eff * 0.002}, 1e-12, "fading");
  expect_near(contact_force(m, {0.02, 0, 0.001}, {0, 0, 0}, 1e-3), {0, 0, 0}, 0, "outside");
  m.valid_radius = -1;
  EXPECT_NE(error_of([&] { validate(m); }).find("valid_radius"), std::string::npos);
}

TEST(HapticsCuttingProxy, TheTissueLoadsLikeASpringThenTheFrontAdvancesAtTheRuptureForce) {
  CuttingResistance term;
  term.direction = {1, 0, 0};
  term.force = 3.0;
  term.stiffness = 500;  // rupture after F / k = 6 mm
  CuttingProxy proxy;
  expect_near(proxy.tick(term, 3.0, {0, 0, 0}, 1e-3), {0, 0, 0}, 0, "a new cut starts unloaded at the hand");
  expect_near(proxy.tick(term, 3.0, {0.002, 0.001, 0}, 1e-3), {-1.0, 0, 0}, 1e-12, "loading: k s along the motion only");
  expect_near(proxy.tick(term, 3.0, {0.010, 0, 0}, 1e-3), {-3.0, 0, 0}, 1e-12, "cutting: the rupture force");
  EXPECT_NEAR(proxy.front()[0], 0.004, 1e-15);  // the front 6 mm behind the hand
  expect_near(proxy.tick(term, 3.0, {0.008, 0, 0}, 1e-3), {-2.0, 0, 0}, 1e-12, "backing off: the spring unloads");
  expect_near(proxy.tick(term, 3.0, {0.003, 0, 0}, 1e-3), {0, 0, 0}, 0, "behind the front: nothing, it never pulls");
  EXPECT_NEAR(proxy.front()[0], 0.004, 1e-15);  // a crack does not heal
  expect_near(proxy.tick(term, 3.0, {0.012, 0, 0}, 1e-3), {-3.0, 0, 0}, 1e-12, "forward again: reloaded, then cutting");
  // A lower level (a fade) caps it, the level held falling at kFallRate: 10 mN a tick.
  expect_near(proxy.tick(term, 1.5, {0.012, 0, 0}, 1e-3), {-2.99, 0, 0}, 1e-12, "a lower level: falling to it");
  for (int tick = 1; tick < 150; ++tick) proxy.tick(term, 1.5, {0.012, 0, 0}, 1e-3);
  expect_near(proxy.tick(term, 1.5, {0.012, 0, 0}, 1e-3), {-1.5, 0, 0}, 1e-9, "a lower level caps it");
  // No level: the spring lets go at the same rate along its axis, then disengages.
  CuttingResistance none;  // the default direction (+x) and no force: the axis is kept
  none.direction = {0, 1, 0};
  expect_near(proxy.tick(none, 0.0, {0.012, 0, 0}, 1e-3), {-1.49, 0, 0}, 1e-9, "no level: letting go");
  for (int tick = 1; tick < 148; ++tick) proxy.tick(none, 0.0, {0.012, 0, 0}, 1e-3);
  EXPECT_TRUE(proxy.engaged());
  proxy.tick(none, 0.0, {0.012, 0, 0}, 1e-3);
  expect_near(proxy.tick(none, 0.0, {0.012, 0, 0}, 1e-3), {0, 0, 0}, 0, "no level: let go");
  EXPECT_FALSE(proxy.engaged());
  expect_near(proxy.tick(term, 3.0, {0.020, 0, 0}, 1e-3), {0, 0, 0}, 0, "the next cut starts unloaded");
}

// A hand drawn back and forth at 5 cm/s through a cutting model, ticked at 1 kHz: the force
// changes by at most k |dx| a tick (no step at a stroke's start or end, where a force scaled by
// the hand's speed would jump by the whole rupture force), and over the closed strokes the
// term gives the hand no energy.
TEST(HapticsCuttingProxy, AStrokeFeelsNoJumpAndGetsNoEnergyBack) {
  CuttingResistance term;
  term.direction = {1, 0, 0};
  term.force = 2.0;
  term.stiffness = 500;
  CuttingProxy proxy;
  const double dt = 1e-3, speed = 0.05;
  Vector3 previous_force{}, x{};
  double work_on_hand = 0, largest_jump = 0, peak = 0;
  for (int tick = 0; tick < 4000; ++tick) {
    const double phase = std::fmod(tick * dt, 2.0);  // 1 s forward, 1 s back, twice
    const Vector3 next{phase < 1 ? speed * phase : speed * (2 - phase), 0, 0};
    const Vector3 f = proxy.tick(term, 2.0, next, 1e-3);
    work_on_hand += f[0] * (next[0] - x[0]);
    largest_jump = std::max(largest_jump, std::abs(f[0] - previous_force[0]));
    peak = std::max(peak, std::abs(f[0]));
    previous_force = f;
    x = next;
  }
  EXPECT_NEAR(peak, 2.0, 1e-12);
  EXPECT_LE(largest_jump, term.stiffness * speed * dt * (1 + 1e-9));
  EXPECT_LE(work_on_hand, 0.0);
  // The first stroke cuts 50 mm less the 4 mm the spring takes up; the second meets the crack
  // it made and only loads and unloads the spring. Each tick books the force at its end, which
  // misses the spring's energy by about k dx^2 per loading or unloading tick.
  EXPECT_NEAR(work_on_hand, -2.0 * (speed * 1.0 - 2.0 / 500), 200 * term.stiffness * std::pow(speed * dt, 2));
}

// A blade that pressed down through the tissue and then draws along it: the models' direction
// turns by 90 degrees from one step to the next, the spring's axis turns at kTurnRate, and the
// force on the hand changes by no more than the turn allows in a tick.
TEST(HapticsCuttingProxy, ATurnOfTheBladesMotionTurnsTheLoadSmoothly) {
  CuttingResistance down;
  down.direction = {0, 0, -1};
  down.force = 2.0;
  down.stiffness = 500;
  CuttingProxy proxy;
  const double dt = 1e-3;
  Vector3 x{0, 0, 0}, f{};
  for (int tick = 0; tick < 200; ++tick) f = proxy.tick(down, 2.0, x = {0, 0, -5e-5 * tick}, dt);
  expect_near(f, {0, 0, 2.0}, 1e-12, "cutting downwards");
  CuttingResistance along = down;
  along.direction = {1, 0, 0};
  double largest_jump = 0;
  for (int tick = 0; tick < 600; ++tick) {
    x[0] += 5e-5;  // drawn along at 5 cm/s from here
    const Vector3 next = proxy.tick(along, 2.0, x, dt);
    largest_jump = std::max(largest_jump, std::hypot(next[0] - f[0], next[1] - f[1], next[2] - f[2]));
    f = next;
  }
  expect_near(proxy.direction(), along.direction, 1e-12, "turned to the new motion");
  expect_near(f, {-2.0, 0, 0}, 1e-9, "cutting along");
  // A tick's turn changes the force by at most F dtheta plus k |x - front| dtheta, and the hand's
  // own motion by k dx.
  const double turn = CuttingProxy::kTurnRate * dt;
  EXPECT_LE(largest_jump, 2.0 * turn + 2.0 * turn + 500 * 5e-5 + 1e-12);
}

// Physics publishes a cutting model once a step, its level ramped 0.1 N a step (the session's
// 10 N/s at dt = 10 ms), but in real time the steps come unevenly: a slow cut step, then quick
// ones that catch up. A model arriving while the one before is still fading in cuts that fade
// short (the new one fades over the last interval, the one it replaces drops out), so a level
// that falls by a step's ramp fell within a tick: the loaded spring let go of up to 0.1 N at
// once. The hand, on a ScriptedDevice, draws through at 5 cm/s while the level rises to 2 N,
// holds and falls back to 0, with publications 1 to 25 ms apart: the force changes a tick by at
// most the spring's k v T plus the level's kFallRate T, at publications as between them.
TEST(HapticsCuttingProxy, APublicationWhileCuttingChangesTheForceNoMoreThanATickOfCutting) {
  ScriptedDevice device;
  ContactModel model;  // no contacts, no domain: the cutting term alone
  model.cutting.direction = {1, 0, 0};
  model.cutting.stiffness = 500;
  ContactChannel channel(model);
  HapticLoop loop(device, channel);
  const std::int64_t intervals_ms[] = {10, 25, 2, 3, 10, 18, 1, 1, 10, 7};
  const double speed = 0.05, ramp = 0.1;
  std::int64_t next_publication = 0;
  int published = 0;
  double level = 0, at_publication = 0, between = 0, peak = 0;
  Vector3 previous{};
  std::uint64_t previous_step = 0;
  for (std::int64_t k = 0; k < 3000; ++k) {
    if (k == next_publication) {
      ++published;
      // Rising for 20 models, held for 40, falling for 20 and again.
      const int phase = published % 80;
      level = phase < 20 ? std::min(2.0, level + ramp) : (phase < 60 ? level : std::max(0.0, level - ramp));
      model.cutting.force = level;
      model.step = static_cast<std::uint64_t>(published);
      channel.write(model);
      next_publication += intervals_ms[published % std::size(intervals_ms)];
    }
    device.pose.position = {speed * 1e-3 * static_cast<double>(k), 0, 0};
    const TickSample s = loop.tick(k * kMs);
    const double jump = std::hypot(s.force[0] - previous[0], s.force[1] - previous[1], s.force[2] - previous[2]);
    if (k > 0) {
      double& largest = s.contact_step != previous_step ? at_publication : between;
      largest = std::max(largest, jump);
    }
    peak = std::max(peak, std::abs(s.cutting_force[0]));
    previous = s.force;
    previous_step = s.contact_step;
  }
  std::printf("cutting through uneven publications: jump a tick %.4f N at publications, %.4f N between, peak %.2f N, "
              "device energy %.3g J\n",
              at_publication, between, peak, loop.passivity().device_energy_J);
  EXPECT_NEAR(peak, 2.0, 1e-9);
  const double bound = 500 * speed * 1e-3 + CuttingProxy::kFallRate * 1e-3;
  EXPECT_LE(at_publication, bound * (1 + 1e-9));
  EXPECT_LE(between, bound * (1 + 1e-9));
  EXPECT_LE(loop.passivity().device_energy_J, 0.0);
}

// Pressing into tissue that yields under the hand (its surface follows half the hand's depth,
// as each model found it) through strokes 10 mm deep, models published 1 to 25 ms apart in
// the loop's time: a model that arrives while the one before still fades in must not drop
// the unfinished part of that fade. Returns the largest change of the force in a tick at a
// publication and between them, and the largest the hand's motion alone gives against one
// fixed model: k (|dx| + T |dv|) at the stroke's largest speed and acceleration (the spring
// and the lips' damper of k T).
namespace {
struct PressFigures {
  double at_publication = 0, between = 0, hand_alone = 0, device_energy = 0;
};
PressFigures press_through_uneven_publications(bool needle) {
  ScriptedDevice device;
  ContactModel model;
  if (!needle) {
    model.count = 1;
    model.contacts[0].normal = {0, 0, 1};
    model.contacts[0].stiffness = 500;
    model.contacts[0].compliance = 0.001;  // k_eff 333.33 N/m
  } else {  // the needle along z, the tissue holding its tip on a line that follows half the hand's x
    model.needle.axis = {0, 0, -1};
    model.needle.stiffness = 250;  // at most 2.5 N across: under the device's 3 N clamp
  }
  ContactChannel channel(model);
  HapticLoop loop(device, channel);
  const std::int64_t intervals_ms[] = {10, 25, 2, 3, 10, 18, 1, 1, 10, 7, 25, 1, 1, 1, 1, 1, 1, 1, 1, 5};
  const double depth = 0.010, period_s = 0.4, yield = 0.5;
  std::int64_t next_publication = 0;
  int published = 0;
  PressFigures out;
  const double omega = 2 * std::numbers::pi / period_s, k = needle ? 250 : 1.0 / (1.0 / 500 + 0.001);
  out.hand_alone = k * (0.5 * depth * omega * 1e-3 + 1e-3 * 0.5 * depth * omega * omega * 1e-3);
  Vector3 previous{};
  std::uint64_t previous_step = 0;
  for (std::int64_t tick = 0; tick < 4000; ++tick) {
    const double t = 1e-3 * static_cast<double>(tick);
    const double in = 0.5 * depth * (1 - std::cos(2 * std::numbers::pi * t / period_s));
    const Vector3 hand = needle ? Vector3{in, 0, 0} : Vector3{0, 0, -in};
    if (tick == next_publication) {
      ++published;
      if (!needle) model.contacts[0].point = {0, 0, -yield * in};
      if (needle) model.needle.line = {yield * in, 0, 0};
      model.step = static_cast<std::uint64_t>(published);
      channel.write(model);
      next_publication += intervals_ms[published % std::size(intervals_ms)];
    }
    device.pose.position = hand;
    const TickSample s = loop.tick(tick * kMs);
    if (tick > 0) {
      const double jump = std::hypot(s.force[0] - previous[0], s.force[1] - previous[1], s.force[2] - previous[2]);
      double& largest = s.contact_step != previous_step ? out.at_publication : out.between;
      largest = std::max(largest, jump);
    }
    previous = s.force;
    previous_step = s.contact_step;
  }
  out.device_energy = loop.passivity().device_energy_J;
  return out;
}

// Each publication's tick changes the force by no more than the hand's own motion (plus 2 mN),
// as the ticks between publications do, and the device gains no energy.
void expect_continuous_through_uneven_publications(const char* term, bool needle) {
  const PressFigures f = press_through_uneven_publications(needle);
  std::printf("%s through uneven publications: jump a tick %.4f N at publications, %.4f N between, hand alone %.4f N, "
              "device energy %.3g J\n",
              term, f.at_publication, f.between, f.hand_alone, f.device_energy);
  EXPECT_LE(f.at_publication, f.hand_alone + 0.002);
  EXPECT_LE(f.between, f.hand_alone + 0.002);
  EXPECT_LE(f.device_energy, 0.0);
}
}  // namespace

TEST(HapticsLoop, AModelArrivingMidFadeKeepsTheLipsContinuous) {
  expect_continuous_through_uneven_publications("lips", false);
}

TEST(HapticsLoop, AModelArrivingMidFadeKeepsTheNeedlesGripContinuous) {
  expect_continuous_through_uneven_publications("needle", true);
}

TEST(HapticsModelFade, AModelArrivingMidFadeKeepsWhatTheLastTickRenderedAsItsOrigin) {
  ModelFade fade;
  ModelFade::Weights w;
  ContactModel m;
  const auto publish = [&](std::uint64_t step, std::int64_t at_ms) {
    m.step = step;
    fade.publish(m, at_ms * kMs, -1, 50 * kMs);
  };
  const auto sum = [&](int n) {
    double total = 0;
    for (int i = 0; i < n; ++i) total += w[i].weight;
    return total;
  };
  publish(1, 0);
  ASSERT_EQ(fade.weights(0, kMs, w), 1);
  EXPECT_EQ(w[0].weight, 1.0);
  publish(2, 25);  // fades in over the 25 ms model 1 lasted
  for (std::int64_t k = 25; k < 30; ++k) ASSERT_EQ(fade.weights(k * kMs, kMs, w), 2);
  EXPECT_DOUBLE_EQ(w[0].weight, 5.0 / 25);  // at the tick at 29 ms
  publish(3, 30);  // 5 ms later: model 2 had reached 0.2, its fade had 20 ms left
  EXPECT_EQ(fade.blend_over_ns(), 20 * kMs);
  ASSERT_EQ(fade.weights(30 * kMs, kMs, w), 3);
  EXPECT_EQ(w[0].model->step, 3u);
  EXPECT_DOUBLE_EQ(w[0].weight, 1.0 / 20);
  EXPECT_EQ(w[1].model->step, 2u);
  EXPECT_DOUBLE_EQ(w[1].weight, 0.2 * 19 / 20);
  EXPECT_EQ(w[2].model->step, 1u);
  EXPECT_DOUBLE_EQ(w[2].weight, 0.8 * 19 / 20);
  for (std::int64_t k = 31; k < 49; ++k) EXPECT_EQ(fade.weights(k * kMs, kMs, w), 3);
  ASSERT_EQ(fade.weights(49 * kMs, kMs, w), 1);  // over when the interrupted fade was due
  EXPECT_EQ(w[0].weight, 1.0);
  // A model a millisecond for 20 ms after a slow one: the origin holds at most kCapacity
  // models, the shares always summing to 1.
  publish(4, 75);
  for (std::int64_t k = 75; k < 100; ++k) {
    if (k > 75) publish(static_cast<std::uint64_t>(k - 70), k);
    const int n = fade.weights(k * kMs, kMs, w);
    EXPECT_LE(fade.origin_count(), ModelFade::kCapacity);
    EXPECT_NEAR(sum(n), 1.0, 1e-12) << "tick " << k;
  }
  EXPECT_EQ(fade.origin_count(), ModelFade::kCapacity);
}

TEST(HapticsCuttingProxy, ABlendWeighsEachModelsLevelByItsDomainAndTheFade) {
  ContactModel now, before;
  now.cutting.force = 4.0;
  now.cutting.direction = {0, 1, 0};
  before.cutting.force = 2.0;
  before.cutting.direction = {1, 0, 0};
  BlendedCutting b = blend_cutting(now, &before, 0.25, {0, 0, 0});
  EXPECT_DOUBLE_EQ(b.level, 0.25 * 4.0 + 0.75 * 2.0);
  EXPECT_EQ(b.term.direction, before.cutting.direction);  // the stronger part's direction
  b = blend_cutting(now, nullptr, 1.0, {0, 0, 0});
  EXPECT_DOUBLE_EQ(b.level, 4.0);
  now.linearised_at = {0, 0, 0};
  now.valid_radius = 0.01;
  EXPECT_DOUBLE_EQ(blend_cutting(now, nullptr, 1.0, {0.0075, 0, 0}).level, 2.0);  // half way out of its domain
  EXPECT_NO_THROW(validate(now));
  now.cutting.stiffness = 0;
  EXPECT_NE(error_of([&] { validate(now); }).find("ContactModel.cutting.stiffness 0.000000 is not > 0"), std::string::npos);
  now.cutting.stiffness = 500;
  now.cutting.force = -1;
  EXPECT_EQ(error_of([&] { validate(now); }), "ContactModel.cutting.force -1.000000 is not >= 0");
  now.cutting.force = 1;
  now.cutting.direction = {0.5, 0, 0};
  EXPECT_NE(error_of([&] { validate(now); }).find("ContactModel.cutting.direction is not unit"), std::string::npos);
}

TEST(HapticsCoupling, ForceIsClampedToTheDeviceLimitKeepingItsDirection) {
  bool clamped = false;
  const Vector3 f = clamp_force({3, 4, 0}, 2.5, &clamped);
  EXPECT_TRUE(clamped);
  expect_near(f, {1.5, 2, 0}, 1e-15, "clamped");
  EXPECT_EQ(clamp_force({0.3, 0.4, 0}, 2.5, &clamped), (Vector3{0.3, 0.4, 0}));
  EXPECT_FALSE(clamped);
  EXPECT_EQ(clamp_force({std::nan(""), 1, 0}, 2.5, &clamped), (Vector3{0, 0, 0}));

  // In the loop: a proxy 10 cm away asks for 30 N; the device allows 3 N.
  ScriptedDevice device;
  ContactChannel channel;
  ContactModel far;
  far.has_proxy = true;
  far.proxy_position = {0, -0.1, 0};
  channel.write(far);
  HapticLoop loop(device, channel);
  for (int k = 0; k < 5; ++k) {
    const TickSample s = loop.tick(k * kMs);
    EXPECT_TRUE(s.clamped);
    expect_near(s.force, {0, -3, 0}, 1e-12, "tick " + std::to_string(k));
    EXPECT_EQ(device.written, s.force);
  }
}

// The loop on its own thread for a few hundred ticks, a virtual device held still at 1 mm in
// the tissue, 2 mm from the proxy: every tick renders K (proxy - x) + k_eff depth n.
TEST(HapticsLoop, ThreadRendersTheExpectedForceForAKnownModelAndPose) {
  VirtualDevice device;
  device.open();
  DevicePose pose;
  pose.position = {0, 0, 0.001};
  pose.buttons = 1;
  device.set_pose(pose);
  ContactChannel channel;
  ContactModel model = known_model();
  validate(model);
  channel.write(model);
  HapticLoopConfig config;
  config.ring_capacity = 1 << 14;
  HapticLoop loop(device, channel, config);
  const double k_eff = 1.0 / (1.0 / 500 + 0.001);
  const Vector3 expected{300 * 0.002, 0, k_eff * 0.001};

  loop.start();
  std::vector<TickSample> samples;
  const auto give_up = std::chrono::steady_clock::now() + std::chrono::seconds(30);
  while (samples.size() < 400 && std::chrono::steady_clock::now() < give_up) {  // physics' side: drain
    loop.samples().drain([&](const TickSample& s) { samples.push_back(s); });
    std::this_thread::sleep_for(std::chrono::milliseconds(5));
  }
  loop.stop();
  loop.samples().drain([&](const TickSample& s) { samples.push_back(s); });
  ASSERT_GE(samples.size(), 400u);
  for (std::size_t i = 0; i < samples.size(); ++i) {
    const TickSample& s = samples[i];
    ASSERT_EQ(s.tick, i) << "every tick reaches physics, in order";
    EXPECT_EQ(s.state, DeviceState::ok);
    EXPECT_EQ(s.pose.position, pose.position);
    EXPECT_EQ(s.pose.buttons, 1u);
    EXPECT_EQ(s.contact_step, 7u);
    EXPECT_FALSE(s.clamped);
    expect_near(s.force, expected, 1e-12, "tick " + std::to_string(i));
  }
  EXPECT_EQ(loop.ring_overflows(), 0u);
  EXPECT_EQ(device.last_force(), (Vector3{0, 0, 0})) << "stop() leaves the device at zero force";
  const PeriodStatistics p = loop.period_statistics();
  std::printf("loop thread: %zu ticks, force (%.4f, %.4f, %.4f) N each; periods p50 %.1f us, p99 %.1f us, max %.1f us "
              "(realtime priority: %s)\n",
              samples.size(), expected[0], expected[1], expected[2], p.p50_us, p.p99_us, p.max_us,
              loop.realtime() ? "yes" : "no");
}

// On simulated time (what headless replay does): a replay device moving at 1 cm/s along x into
// a proxy at rest; the damper term B (v_proxy - v) with B = K T, and a new ContactModel taking
// effect on the next tick.
TEST(HapticsLoop, SimulatedTicksIncludeTheDamperAndFollowNewModels) {
  ManualClock clock(0);
  ReplayDevice device({{0.0, DevicePose{{0, 0, 0.001}, {1, 0, 0, 0}, 0}}, {1.0, DevicePose{{0.01, 0, 0.001}, {1, 0, 0, 0}, 0}}},
                      DeviceLimits{}, clock.clock());
  device.open();
  ContactChannel channel;
  ContactModel model = known_model();
  model.proxy_position = {0, 0, 0.001};
  channel.write(model);
  HapticLoopConfig config;
  config.blend_ns = 0;  // a new model at once (the fade is the next test's)
  HapticLoop loop(device, channel, config);
  const double K = 300, B = 300 * 1e-3, k_eff = 1.0 / (1.0 / 500 + 0.001);
  for (int k = 0; k < 300; ++k) {
    if (k == 200) {  // physics publishes a model without contact (say the tool was lifted by a cut)
      ContactModel lifted = model;
      lifted.count = 0;
      lifted.step = 8;
      channel.write(lifted);
    }
    clock.set_ns(k * kMs);
    const TickSample s = loop.tick(k * kMs);
    const double x = 0.01 * k * 1e-3;
    const double v = k == 0 ? 0.0 : 0.01;  // the first tick has no difference yet
    const double contact = k < 200 ? k_eff * 0.001 : 0.0;
    expect_near(s.force, {K * (0 - x) + B * (0 - v), 0, contact}, 1e-9, "tick " + std::to_string(k));
    EXPECT_EQ(s.contact_step, k < 200 ? 7u : 8u);
  }
  EXPECT_EQ(device.last_force()[2], 0.0);
}

// By default a new model fades in over the interval between the last two (the physics step),
// the old one fading out, so that the tissue's motion over a step is not felt as a jump: the
// device held 1 mm inside the contact of a model published at t = 0, a model without contact
// at 10 ms (the physics step) takes the force down in ten equal steps, and one with the
// contact again at 30 ms takes it back up over 20 ms.
TEST(HapticsLoop, ANewModelFadesInOverTheIntervalBetweenModels) {
  ScriptedDevice device;
  device.pose.position = {0, 0, 0.001};
  ContactModel touching = known_model();
  touching.step = 1;
  ContactChannel channel(touching);
  HapticLoop loop(device, channel);
  const double full = 1.0 / (1.0 / 500 + 0.001) * 0.001;  // the contact's force 1 mm deep
  double largest_change = 0, previous = 0;
  for (int k = 0; k < 60; ++k) {
    if (k == 10) {
      ContactModel lifted = touching;
      lifted.count = 0;
      lifted.step = 2;
      channel.write(lifted);
    }
    if (k == 30) {
      touching.step = 3;
      channel.write(touching);
    }
    const double force = loop.tick(k * kMs).contact_force[2];
    double expected = full;  // the first model at once
    if (k >= 10 && k < 30) expected = full * std::max(0.0, 1 - (k - 10 + 1) / 10.0);
    if (k >= 30) expected = full * std::min(1.0, (k - 30 + 1) / 20.0);
    EXPECT_NEAR(force, expected, 1e-12 * full) << "tick " << k;
    if (k > 0) largest_change = std::max(largest_change, std::abs(force - previous));
    previous = force;
  }
  EXPECT_NEAR(largest_change, full / 10, 1e-12 * full);  // was `full` in one tick
  // 0 keeps the old behaviour: the model in effect from the next tick, whole.
  HapticLoopConfig at_once;
  at_once.blend_ns = 0;
  ContactChannel channel_at_once(touching);
  HapticLoop immediate(device, channel_at_once, at_once);
  EXPECT_NEAR(immediate.tick(0).contact_force[2], full, 1e-12 * full);
  ContactModel lifted = touching;
  lifted.count = 0;
  lifted.step = 4;
  channel_at_once.write(lifted);
  EXPECT_EQ(immediate.tick(kMs).contact_force[2], 0.0);
  HapticLoopConfig bad;
  bad.blend_ns = -2;
  EXPECT_THROW(HapticLoop(device, channel, bad), std::invalid_argument);
}

TEST(HapticsLoop, LostDeviceGetsZeroForce) {
  ScriptedDevice device;
  device.pose.position = {0, 0, 0.001};
  ContactChannel channel(known_model());
  HapticLoop loop(device, channel);
  EXPECT_GT(loop.tick(0).force[2], 0.0);
  device.current = DeviceState::lost;
  const TickSample s = loop.tick(kMs);
  EXPECT_EQ(s.force, (Vector3{0, 0, 0}));
  EXPECT_EQ(device.written, (Vector3{0, 0, 0}));
  EXPECT_EQ(s.state, DeviceState::lost);
  EXPECT_GT(s.contact_force[2], 0.0) << "the model is still evaluated, only not rendered";
  device.current = DeviceState::ok;
  EXPECT_GT(loop.tick(2 * kMs).force[2], 0.0);
}

// Prints the loop's period percentiles beside a bare clock_nanosleep loop's, measured in this
// run, sleep-only and sleep-then-spin. Nothing here is asserted about time.
// INCISE_HAPTIC_TIMING_SECONDS sets each run's length (default 1 s).
TEST(HapticsLoopTiming, PrintsPeriodsBesideABareLoop) {
  double seconds = 1.0;
  if (const char* s = std::getenv("INCISE_HAPTIC_TIMING_SECONDS")) seconds = std::atof(s);
  const auto duration = static_cast<std::int64_t>(seconds * 1e9);
  auto print = [](const char* what, const PeriodStatistics& p) {
    std::printf("%-28s periods %7llu  p50 %7.1f us  p99 %7.1f us  p99.9 %7.1f us  max %8.1f us  >2ms %llu  missed %llu\n",
                what, static_cast<unsigned long long>(p.periods), p.p50_us, p.p99_us, p.p999_us, p.max_us,
                static_cast<unsigned long long>(p.over_2ms), static_cast<unsigned long long>(p.missed_deadlines));
  };
  for (std::int64_t spin_ns : {std::int64_t{0}, std::int64_t{400'000}}) {
    HapticLoopConfig config;
    config.spin_ns = spin_ns;
    config.ring_capacity = 1 << 16;
    print(spin_ns == 0 ? "bare loop, sleep only" : "bare loop, spin 400 us", measure_bare_loop(config, duration));

    VirtualDevice device;
    device.open();
    DevicePose pose;
    pose.position = {0, 0, 0.001};
    device.set_pose(pose);
    ContactChannel channel(known_model());
    HapticLoop loop(device, channel, config);
    loop.start();
    std::uint64_t drained = 0;
    const auto end = std::chrono::steady_clock::now() + std::chrono::nanoseconds(duration);
    while (std::chrono::steady_clock::now() < end) {  // a physics-like consumer at ~100 Hz
      drained += loop.samples().drain([](const TickSample&) {});
      std::this_thread::sleep_for(std::chrono::milliseconds(10));
    }
    loop.stop();
    print(spin_ns == 0 ? "haptic loop, sleep only" : "haptic loop, spin 400 us", loop.period_statistics());
    std::printf("%-28s ticks %llu, drained %llu, realtime priority %s\n", "", static_cast<unsigned long long>(loop.ticks()),
                static_cast<unsigned long long>(drained), loop.realtime() ? "yes" : "no (not permitted)");
    EXPECT_GT(loop.ticks(), 0u);
  }
}
