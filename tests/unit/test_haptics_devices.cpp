// The replay, virtual and path devices: interpolation by time, validation with clear errors,
// the virtual device's lock-free setter read from another thread, and the path device (the
// bench's scripted hand) read at the loop's time.
#include <gtest/gtest.h>

#include <atomic>
#include <cmath>
#include <limits>
#include <thread>

#include "bench/scripted_stroke.hpp"
#include "haptics/haptic_loop.hpp"
#include "haptics/path_device.hpp"
#include "haptics/replay_device.hpp"
#include "haptics/virtual_device.hpp"

using namespace incise::haptics;

namespace {

DevicePose at(double x, double y, double z, std::uint32_t buttons = 0, Quaternion q = {1, 0, 0, 0}) {
  DevicePose p;
  p.position = {x, y, z};
  p.orientation = q;
  p.buttons = buttons;
  return p;
}

template <typename F>
std::string error_of(F&& f) {
  try {
    f();
  } catch (const std::invalid_argument& e) {
    return e.what();
  }
  return "(no error)";
}

}  // namespace

TEST(HapticsReplay, InterpolatesLinearlyByTime) {
  const double h = std::sqrt(0.5);
  ManualClock clock(5'000'000'000);
  ReplayDevice device({{1.0, at(0, 0, 0, 0)},
                       {2.0, at(0.01, -0.02, 0.04, 1, {h, 0, 0, h})},  // 90 degrees about z
                       {4.0, at(0.03, 0.0, 0.0, 3, {-h, 0, 0, -h})}},   // same rotation, other sign
                      DeviceLimits{}, clock.clock());
  // Between samples 0 and 1, a quarter of the way.
  const DevicePose q = device.pose_at(1.25);
  EXPECT_DOUBLE_EQ(q.position[0], 0.0025);
  EXPECT_DOUBLE_EQ(q.position[1], -0.005);
  EXPECT_DOUBLE_EQ(q.position[2], 0.01);
  EXPECT_EQ(q.buttons, 0u);  // held from the earlier sample
  const double n = std::hypot(0.75 + 0.25 * h, 0.25 * h);
  EXPECT_NEAR(q.orientation[0], (0.75 + 0.25 * h) / n, 1e-15);
  EXPECT_NEAR(q.orientation[3], 0.25 * h / n, 1e-15);
  // Between 1 and 2: the sign flip is taken as the same rotation (no swing through identity).
  const DevicePose r = device.pose_at(3.0);
  EXPECT_DOUBLE_EQ(r.position[0], 0.02);
  EXPECT_DOUBLE_EQ(r.position[2], 0.02);
  EXPECT_EQ(r.buttons, 1u);
  EXPECT_NEAR(r.orientation[0], h, 1e-15);
  EXPECT_NEAR(r.orientation[3], h, 1e-15);
  // Exactly at a sample, and held outside the range.
  EXPECT_EQ(device.pose_at(2.0).position, (Vector3{0.01, -0.02, 0.04}));
  EXPECT_EQ(device.pose_at(-10).position, (Vector3{0, 0, 0}));
  EXPECT_EQ(device.pose_at(10).buttons, 3u);

  // Played on the device's clock from open(): playback time = 1.0 s + elapsed.
  device.open();
  EXPECT_EQ(device.state(), DeviceState::ok);
  EXPECT_EQ(device.read_pose().position, (Vector3{0, 0, 0}));
  for (double elapsed : {0.25, 0.5, 1.0, 1.7, 2.0, 2.999}) {
    clock.set_ns(5'000'000'000 + static_cast<std::int64_t>(std::llround(elapsed * 1e9)));
    const DevicePose played = device.read_pose();
    const DevicePose expected = device.pose_at(1.0 + elapsed);
    for (int i = 0; i < 3; ++i) EXPECT_NEAR(played.position[i], expected.position[i], 1e-15) << elapsed;
    EXPECT_EQ(played.buttons, expected.buttons);
    EXPECT_FALSE(device.finished());
  }
  clock.set_ns(9'000'000'000);
  EXPECT_EQ(device.read_pose().position, (Vector3{0.03, 0, 0}));
  EXPECT_TRUE(device.finished());
  device.write_force({0, 0, 1});
  EXPECT_EQ(device.last_force(), (Vector3{0, 0, 1}));
}

TEST(HapticsReplay, RejectsBadSamplesNamingThem) {
  EXPECT_EQ(error_of([] { ReplayDevice d({}); }), "replay device: no samples");
  const double nan = std::numeric_limits<double>::quiet_NaN();
  EXPECT_EQ(error_of([&] { ReplayDevice d({{0, at(0, 0, 0)}, {1, at(nan, 0, 0)}}); }),
            "replay device samples[1].pose.position[0] is not finite (nan)");
  EXPECT_EQ(error_of([&] { ReplayDevice d({{0, at(0, 0, 0)}, {0, at(0, 0, 0)}}); }),
            "replay device samples[1].time_s 0.000000 is not after the previous sample's 0.000000");
  EXPECT_NE(error_of([&] { ReplayDevice d({{0, at(0, 0, 0, 0, {2, 0, 0, 0})}}); }).find("not a unit quaternion"),
            std::string::npos);
}

TEST(HapticsVirtual, SetPoseClampsToTheWorkspaceAndRejectsNonFinite) {
  DeviceLimits limits;
  limits.workspace_min = {-0.1, -0.1, -0.1};
  limits.workspace_max = {0.1, 0.1, 0.1};
  VirtualDevice device(limits);
  EXPECT_EQ(device.state(), DeviceState::closed);
  device.open();
  EXPECT_EQ(device.state(), DeviceState::ok);
  const DevicePose stored = device.set_pose(at(0.5, -0.05, -0.3, 1, {1.0004, 0, 0, 0}));
  EXPECT_EQ(stored.position, (Vector3{0.1, -0.05, -0.1}));
  EXPECT_DOUBLE_EQ(stored.orientation[0], 1.0);
  const DevicePose read = device.read_pose();
  EXPECT_EQ(read.position, stored.position);
  EXPECT_EQ(read.buttons, 1u);

  EXPECT_EQ(error_of([&] { device.set_pose(at(0, std::numeric_limits<double>::infinity(), 0)); }),
            "virtual device pose.position[1] is not finite (inf)");
  EXPECT_NE(error_of([&] { device.set_pose(at(0, 0, 0, 0, {0, 0, 0, 0})); }).find("not a unit quaternion (|q| = 0"),
            std::string::npos);
  EXPECT_EQ(device.read_pose().position, stored.position);  // rejected poses change nothing
}

// The window thread sets poses while the haptic thread reads: every read is one whole pose.
TEST(HapticsVirtual, ReadsWhileTheWindowWritesAreNeverTorn) {
  DeviceLimits limits;
  limits.workspace_min = {-1e9, -1e9, -1e9};
  limits.workspace_max = {1e9, 1e9, 1e9};
  VirtualDevice device(limits);
  device.open();
  constexpr std::uint32_t kWrites = 100'000;
  std::atomic<bool> finished{false};
  std::thread window([&] {
    for (std::uint32_t k = 1; k <= kWrites; ++k) {
      const double a = 0.5 * k;
      device.set_pose(at(k, 2.0 * k, 3.0 * k, k, {std::cos(a), 0, std::sin(a), 0}));
    }
    finished.store(true);
  });
  std::uint64_t reads = 0, changes = 0;
  double previous = 0;
  while (!finished.load() || reads == 0) {
    const DevicePose p = device.read_pose();
    ++reads;
    const double k = p.position[0];
    if (k == 0) continue;  // still the initial centre
    ASSERT_EQ(p.position[1], 2 * k);
    ASSERT_EQ(p.position[2], 3 * k);
    ASSERT_EQ(p.buttons, static_cast<std::uint32_t>(k));
    ASSERT_NEAR(p.orientation[0], std::cos(0.5 * k), 1e-12);
    ASSERT_NEAR(p.orientation[2], std::sin(0.5 * k), 1e-12);
    ASSERT_GE(k, previous);  // never back in time
    if (k != previous) ++changes;
    previous = k;
  }
  window.join();
  EXPECT_EQ(device.read_pose().position[0], kWrites);
  std::printf("virtual device: %llu reads saw %llu distinct poses of %u written, none torn\n",
              static_cast<unsigned long long>(reads), static_cast<unsigned long long>(changes), kWrites);
}

// The bench's hand is where the script says at the moment the loop reads it, whenever that is:
// read directly and through a tick at the same time, the pose at t is scripted_stroke(t), on
// each phase of the stroke (press, draw, lift, back) and lanes on; before its start, t = 0.
TEST(HapticsPath, ThePoseReadAtTimeTIsTheScriptedStrokeAtT) {
  ManualClock clock(5'000'000'000);
  PathDevice device([](double t) { return incise::bench::scripted_stroke(t, true); }, clock.clock());
  device.open();
  const auto expect_pose = [](const DevicePose& read, const DevicePose& expected, const std::string& what) {
    for (int i = 0; i < 3; ++i) EXPECT_EQ(read.position[i], expected.position[i]) << what << " [" << i << "]";
    EXPECT_EQ(read.buttons, expected.buttons) << what;
    EXPECT_EQ(read.orientation, expected.orientation) << what;
  };
  expect_pose(device.read_pose(), incise::bench::scripted_stroke(0, true), "before the start");

  const std::int64_t t0 = clock.now_ns() + 1'234'567;
  device.start_at(t0);
  expect_pose(device.read_pose(), incise::bench::scripted_stroke(0, true), "a read before t0");
  ContactChannel channel;
  HapticLoop loop(device, channel);
  for (const double t : {0.0, 0.1504, 0.3, 0.8123457, 1.4999, 1.6, 1.9, 2.0005, 5.25, 9.87654321}) {
    const std::int64_t now = t0 + static_cast<std::int64_t>(std::llround(t * 1e9));
    clock.set_ns(now);
    const double at = 1e-9 * static_cast<double>(now - t0);
    const DevicePose expected = incise::bench::scripted_stroke(at, true);
    expect_pose(device.read_pose(), expected, "read at t = " + std::to_string(t));
    expect_pose(loop.tick(now).pose, expected, "tick at t = " + std::to_string(t));
  }
  // The script moves: the draw's x at 0.9 s is half way across, engaged; lifted at 1.6 s.
  clock.set_ns(t0 + 900'000'000);
  EXPECT_NEAR(device.read_pose().position[0], 0.0, 1e-12);
  EXPECT_EQ(device.read_pose().buttons, kButtonEngage);
  clock.set_ns(t0 + 1'600'000'000);
  EXPECT_EQ(device.read_pose().buttons, 0u);
}

TEST(HapticsPath, ClampsToTheWorkspaceAndWritesNoForceWhenClosed) {
  DeviceLimits limits;
  limits.workspace_max = {0.05, 0.05, 0.05};
  ManualClock clock;
  PathDevice device([](double t) { return at(t, -1.0, 0.01); }, clock.clock(), limits);
  device.start_at(0);
  clock.set_ns(80'000'000);
  const DevicePose p = device.read_pose();
  EXPECT_DOUBLE_EQ(p.position[0], 0.05);  // 0.08 clamped
  EXPECT_DOUBLE_EQ(p.position[1], -0.1);
  EXPECT_DOUBLE_EQ(p.position[2], 0.01);
  EXPECT_EQ(device.state(), DeviceState::closed);
  device.write_force({1, 2, 3});
  EXPECT_EQ(device.last_force(), (Vector3{0, 0, 0}));
  device.open();
  device.write_force({1, 2, 3});
  EXPECT_EQ(device.last_force(), (Vector3{1, 2, 3}));
  EXPECT_EQ(error_of([] { PathDevice empty(PathDevice::Path{}); }), "path device: no path");
}
