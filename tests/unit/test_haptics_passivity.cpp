// Time-domain passivity (haptics/passivity.hpp, Hannaford & Ryu 2002): the observer against
// the analytic work of a spring, a sampled spring's known activity, an active environment (a
// spring whose force lags the position) that the controller makes passive, a passive damped
// spring the controller never touches, and the loop's books. The hand here is a prescribed
// motion (a device of infinite impedance), so the same strokes run with and without the
// controller and the environment's own energy is known either way.
#include <gtest/gtest.h>

#include <cmath>
#include <deque>
#include <functional>
#include <numbers>
#include <string>

#include "haptics/haptic_loop.hpp"
#include "haptics/passivity.hpp"
#include "tests/unit/scripted_device.hpp"

using namespace incise::haptics;
using incise::testing::ScriptedDevice;

namespace {

constexpr double kT = 1e-3;       // s, the loop's period
constexpr double kMaxForce = 1e3;  // N, out of the way unless a test wants it

// x(t) along the x axis: `cycles` presses to depth A and back, A (1 - cos(w t)) / 2.
double position(int k, double A, double seconds_per_cycle) {
  const double w = 2 * std::numbers::pi / seconds_per_cycle;
  return 0.5 * A * (1 - std::cos(w * k * kT));
}

struct Stroke {
  double energy = 0, max_energy = 0, environment_energy = 0, max_damper = 0, max_damping = 0, max_damper_step = 0;
  PassivityFigures figures;
};

// Drives a controller through `ticks` ticks of the stroke, the environment's force at tick k
// given by environment(k, positions so far); books the environment's own work independently.
Stroke drive(PassivityController& controller, int ticks, double A, double cycle_s,
          const std::function<double(int, const std::deque<double>&)>& environment) {
  Stroke run;
  std::deque<double> xs;
  double held_environment = 0, previous_damper = 0;
  for (int k = 0; k < ticks; ++k) {
    const double x = position(k, A, cycle_s);
    if (!xs.empty()) run.environment_energy += held_environment * (x - xs.back());
    xs.push_back(x);
    const double f = environment(k, xs);
    const double v = xs.size() >= 2 ? (x - xs[xs.size() - 2]) / kT : 0.0;
    const Vector3 out = controller.tick({x, 0, 0}, {v, 0, 0}, {f, 0, 0}, kT, kMaxForce);
    held_environment = f;
    run.max_energy = std::max(run.max_energy, controller.energy());
    run.max_damper_step = std::max(run.max_damper_step, std::abs(controller.damper_force()[0] - previous_damper));
    previous_damper = controller.damper_force()[0];
    run.max_damper = std::max(run.max_damper, std::abs(controller.damper_force()[0]));
    if (xs.size() >= 2 && xs[xs.size() - 1] != xs[xs.size() - 2])
      run.max_damping =
          std::max(run.max_damping, std::abs(controller.damper_force()[0]) * kT / std::abs(xs[xs.size() - 1] - xs[xs.size() - 2]));
    EXPECT_TRUE(std::isfinite(out[0]));
  }
  run.energy = controller.energy();
  run.figures = controller.figures();
  return run;
}

PassivityController observer_only() {
  PassivityParameters p;
  p.enabled = false;
  return PassivityController(p);
}

}  // namespace

// A spring F = -K x pressed from 0 to d at constant speed in N ticks and released the same way.
// The hand does K d^2 / 2 of work pressing (the continuous integral); the sampled spring holds
// the force of the position before, so the observer's sum is exactly -K D^2 N (N - 1) / 2
// pressing (D = d / N) and, released, K D^2 N (N + 1) / 2: over the closed stroke the sampled
// spring gives the device K d D, Colgate's zero-order-hold activity, which vanishes with T.
TEST(HapticsPassivity, ObserverBooksTheWorkOfASpringStroke) {
  const double K = 400, d = 0.01;
  for (int N : {100, 1000}) {
    PassivityController observer = observer_only();
    const double D = d / N;
    for (int k = 0; k <= N; ++k) observer.tick({k * D, 0, 0}, {}, {-K * k * D, 0, 0}, kT, kMaxForce);
    const double pressed = observer.energy();
    EXPECT_NEAR(pressed, -K * D * D * N * (N - 1) / 2, 1e-12 * K * d * d) << N;
    EXPECT_NEAR(pressed, -K * d * d / 2, K * d * D / 2 * (1 + 1e-9)) << "the continuous integral, within the hold's error";
    for (int k = N - 1; k >= 0; --k) observer.tick({k * D, 0, 0}, {}, {-K * k * D, 0, 0}, kT, kMaxForce);
    EXPECT_NEAR(observer.energy(), K * d * D, 1e-12 * K * d * d) << N;
    EXPECT_EQ(observer.figures().ticks_acted, 0u);
    EXPECT_EQ(observer.figures().dissipated_J, 0.0);
  }
}

// The observer converges to the continuous integral along a smooth stroke too: half a cosine
// stroke into a spring stores K A^2 / 2, the observer's error halving with the period.
TEST(HapticsPassivity, ObserverConvergesToTheContinuousIntegralOfASmoothStroke) {
  const double K = 400, A = 0.01;
  double previous_error = 0;
  for (int N : {200, 400, 800}) {
    PassivityController observer = observer_only();
    const double w = std::numbers::pi / N;  // half a cycle in N ticks
    for (int k = 0; k <= N; ++k) {
      const double x = 0.5 * A * (1 - std::cos(w * k));
      observer.tick({x, 0, 0}, {}, {-K * x, 0, 0}, kT, kMaxForce);
    }
    const double error = std::abs(observer.energy() - (-K * A * A / 2));
    EXPECT_LT(error, 0.01 * K * A * A / 2) << N;
    if (previous_error > 0) {
      EXPECT_NEAR(previous_error / error, 2.0, 0.05) << "first order in T";
    }
    previous_error = error;
  }
}

// An active environment: a spring whose force lags the position by 5 ticks (a slow model, a
// delayed network). Over closed strokes it gives the device energy; with the controller the
// device's net energy stays at most a tick's worth above zero, and the books close: what the
// environment gave equals what the device kept plus what the damper took.
TEST(HapticsPassivity, ControllerMakesALaggingSpringPassiveOverClosedStrokes) {
  const double K = 400, A = 0.01, cycle = 0.5;
  const int ticks = 3 * 500 + 1;  // three closed strokes
  auto lagging = [K](int k, const std::deque<double>& xs) {
    const int lag = 5;
    const double x = k >= lag ? xs[xs.size() - 1 - lag] : 0.0;
    return -K * x;
  };
  PassivityController without = observer_only();
  const Stroke free_run = drive(without, ticks, A, cycle, lagging);
  // The lag acts as a negative damping of about K x 5 ms = 2 N s/m: the cap must exceed it.
  // First Hannaford & Ryu's controller as published, the damper free to jump.
  PassivityParameters parameters;
  parameters.max_damping = 20.0;
  parameters.max_step = 1e3;
  PassivityController with(parameters);
  const Stroke controlled = drive(with, ticks, A, cycle, lagging);

  std::printf("lagging spring, 3 strokes: energy to the device %.3e J without the controller, %.3e J with (max %.3e J); "
              "damper took %.3e J over %llu ticks, at most %.3f N, %.3f N s/m\n",
              free_run.energy, controlled.energy, controlled.max_energy, controlled.figures.dissipated_J,
              static_cast<unsigned long long>(controlled.figures.ticks_acted), controlled.max_damper, controlled.max_damping);
  EXPECT_GT(free_run.energy, 1e-4) << "the lagging spring is active";
  EXPECT_NEAR(free_run.environment_energy, free_run.energy, 1e-15);
  EXPECT_LE(controlled.energy, 1e-3 * free_run.energy);
  EXPECT_LE(controlled.max_energy, 0.05 * free_run.energy) << "never more than a tick's worth above zero";
  EXPECT_GT(controlled.figures.ticks_acted, 0u);
  EXPECT_NEAR(controlled.environment_energy, free_run.energy, 1e-15) << "the hand's path does not depend on the force";
  EXPECT_NEAR(controlled.environment_energy, controlled.energy + controlled.figures.dissipated_J, 1e-12)
      << "environment = device + damper";
  EXPECT_LE(controlled.max_damping, parameters.max_damping * (1 + 1e-9));

  // With the default ramp (max_step per tick) the dissipation is spread over more ticks: most
  // of the excess is still taken within the strokes, and the damper never jumps.
  parameters.max_step = PassivityParameters{}.max_step;
  PassivityController ramped(parameters);
  const Stroke smooth = drive(ramped, ticks, A, cycle, lagging);
  std::printf("with a ramp of %.3f N per tick: %.3e J left (max %.3e J), largest damper step %.4f N\n",
              parameters.max_step, smooth.energy, smooth.max_energy, smooth.max_damper_step);
  EXPECT_LE(smooth.energy, 0.2 * free_run.energy);
  EXPECT_LE(smooth.max_damper_step, parameters.max_step * (1 + 1e-9));
  EXPECT_NEAR(smooth.environment_energy, smooth.energy + smooth.figures.dissipated_J, 1e-12);
}

// The cap: with a damper of at most 0.05 N s/m the controller cannot take everything, and it
// never exceeds the cap or the device's force limit.
TEST(HapticsPassivity, TheDamperIsBoundedByMaxDampingAndTheForceLimit) {
  const double K = 400, A = 0.01, cycle = 0.5;
  auto lagging = [K](int k, const std::deque<double>& xs) { return k >= 5 ? -K * xs[xs.size() - 6] : 0.0; };
  PassivityParameters parameters;
  parameters.max_damping = 0.05;
  PassivityController capped(parameters);
  const Stroke run = drive(capped, 1501, A, cycle, lagging);
  EXPECT_LE(run.max_damping, 0.05 * (1 + 1e-9));
  EXPECT_GT(run.energy, 0.0) << "a capped damper leaves some of the excess";
  PassivityController full;
  Vector3 out{};
  for (int k = 0; k < 100; ++k) out = full.tick({0.001 * k, 0, 0}, {1, 0, 0}, {2.5, 0, 0}, kT, 3.0);  // pushes along the motion
  EXPECT_GT(full.figures().ticks_acted, 0u);
  EXPECT_LE(std::hypot(out[0], out[1], out[2]), 3.0 + 1e-12);
}

// A passive environment: the sampled spring with the loop's damper B = K T on the backward
// difference (Colgate's bound is K T / 2). The device's energy never goes above zero, so the
// controller never acts.
TEST(HapticsPassivity, ControllerNeverActsOnADampedSpring) {
  const double K = 400, A = 0.01;
  for (double cycle : {0.2, 0.5, 2.0}) {
    auto damped = [K](int, const std::deque<double>& xs) {
      const double x = xs.back();
      const double v = xs.size() >= 2 ? (x - xs[xs.size() - 2]) / kT : 0.0;
      return -K * x - K * kT * v;
    };
    PassivityController controller;
    const Stroke run = drive(controller, static_cast<int>(3 * cycle / kT) + 1, A, cycle, damped);
    EXPECT_LE(run.max_energy, 0.0) << cycle;
    EXPECT_LT(run.energy, 0.0) << cycle;
    EXPECT_EQ(run.figures.ticks_acted, 0u) << cycle;
    EXPECT_EQ(run.figures.dissipated_J, 0.0) << cycle;
    EXPECT_EQ(run.max_damper, 0.0) << cycle;
  }
}

TEST(HapticsPassivity, LostDeviceAndBadParameters) {
  PassivityController controller;
  controller.tick({0, 0, 0}, {1, 0, 0}, {1, 0, 0}, kT, kMaxForce);
  controller.tick({0.001, 0, 0}, {1, 0, 0}, {1, 0, 0}, kT, kMaxForce);  // 1 mJ given: the damper starts
  const Vector3 out = controller.tick({0.002, 0, 0}, {1, 0, 0}, {1, 0, 0}, kT, kMaxForce, /*render=*/false);
  EXPECT_EQ(out, (Vector3{0, 0, 0})) << "nothing rendered to a lost device, not even the damper";
  // Tick 1 booked 1 mJ and wrote 1 N less the damper's first step (max_step); tick 2 books
  // (1 N - max_step) x 1 mm, the damper having taken max_step x 1 mm.
  const double step = PassivityParameters{}.max_step;
  EXPECT_NEAR(controller.energy(), 0.001 + (1 - step) * 0.001, 1e-15);
  EXPECT_NEAR(controller.figures().dissipated_J, step * 0.001, 1e-15);
  PassivityParameters bad;
  bad.max_damping = -1;
  try {
    PassivityController refused(bad);
    ADD_FAILURE() << "negative max_damping accepted";
  } catch (const std::invalid_argument& e) {
    EXPECT_EQ(std::string(e.what()), "passivity.max_damping -1.000000 N s/m is negative");
  }
  bad.max_damping = std::nan("");
  EXPECT_THROW(PassivityController{bad}, std::invalid_argument);
}

// In the loop: each tick's device_energy is the running sum of the force written at the tick
// before times the device's displacement since, and passivity() reports the same books.
TEST(HapticsPassivity, TheLoopBooksTheWorkOfTheForceItWrites) {
  ScriptedDevice device;
  ContactModel plane;  // tissue z < 0
  plane.count = 1;
  plane.contacts[0].stiffness = 400;
  plane.step = 1;
  ContactChannel channel(plane);
  HapticLoop loop(device, channel);
  double booked = 0;
  Vector3 held{}, previous{};
  for (int k = 0; k < 2000; ++k) {
    // Into the tissue and out, 3 mm deep, twice.
    device.pose.position = {0, 0, -0.0015 * (1 - std::cos(2 * std::numbers::pi * k / 1000.0))};
    const TickSample s = loop.tick(k * 1'000'000LL);
    if (k > 0)
      for (int i = 0; i < 3; ++i) booked += held[i] * (s.pose.position[i] - previous[i]);
    EXPECT_NEAR(s.device_energy, booked, 1e-15) << k;
    EXPECT_LE(s.device_energy, 1e-12) << "the contact's spring and damper are passive";
    held = s.force;
    previous = s.pose.position;
  }
  EXPECT_NEAR(loop.passivity().device_energy_J, booked, 1e-15);
  EXPECT_EQ(loop.passivity().ticks_acted, 0u);
  EXPECT_LT(booked, 0.0);
}
