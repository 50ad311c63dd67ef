// The udp device over loopback: a bridge-like sender in the test, and the real incise-bridge
// program. The device's loss clock is a ManualClock, so the 50 ms rule is checked without
// sleeping; the only real waiting is for loopback delivery, bounded, never asserted on.
#include <gtest/gtest.h>

#include <arpa/inet.h>
#include <netinet/in.h>
#include <poll.h>
#include <sys/socket.h>
#include <unistd.h>

#include <atomic>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <optional>
#include <string>
#include <thread>
#include <vector>

#include "haptics/udp_device.hpp"

using namespace incise::haptics;
using protocol::Verdict;

namespace {

constexpr std::int64_t kMs = 1'000'000;

// What a bridge does, minus the device: send pose packets, read force packets.
class Sender {
 public:
  explicit Sender(std::uint16_t device_port) {
    fd_ = socket(AF_INET, SOCK_DGRAM | SOCK_CLOEXEC, 0);
    sockaddr_in a{};
    a.sin_family = AF_INET;
    a.sin_port = htons(device_port);
    inet_pton(AF_INET, "127.0.0.1", &a.sin_addr);
    EXPECT_EQ(connect(fd_, reinterpret_cast<sockaddr*>(&a), sizeof a), 0);
  }
  ~Sender() { close(fd_); }
  void send_bytes(const std::uint8_t* data, std::size_t size) {
    ASSERT_EQ(send(fd_, data, size, 0), static_cast<ssize_t>(size));
  }
  void send_pose(const protocol::PosePacket& p) {
    const auto b = protocol::encode(p);
    send_bytes(b.data(), b.size());
  }
  // The next force packet, waiting up to 2 s for it (delivery, not timing, is the point).
  std::optional<protocol::ForcePacket> receive_force() {
    pollfd p{fd_, POLLIN, 0};
    if (poll(&p, 1, 2000) != 1) return std::nullopt;
    std::uint8_t buffer[256];
    const ssize_t n = recv(fd_, buffer, sizeof buffer, 0);
    protocol::ForcePacket f;
    if (n <= 0 || protocol::decode_force(buffer, static_cast<std::size_t>(n), f) != Verdict::accepted) return std::nullopt;
    return f;
  }

 private:
  int fd_ = -1;
};

// Reads the device until it has looked at `datagrams` more datagrams (loopback delivers at
// once in practice; the bound only keeps a broken build from hanging).
void pump(UdpDevice& device, std::uint64_t datagrams) {
  const std::uint64_t target = device.statistics().received + datagrams;
  for (int i = 0; i < 200000 && device.statistics().received < target; ++i) {
    device.read_pose();
    if (device.statistics().received < target) std::this_thread::yield();
  }
  ASSERT_GE(device.statistics().received, target) << "loopback datagrams did not arrive";
}

protocol::PosePacket pose_packet(std::uint64_t sequence, std::int64_t timestamp_ns, double x,
                                 std::uint32_t session = 77) {
  protocol::PosePacket p;
  p.session = session;
  p.sequence = sequence;
  p.timestamp_ns = timestamp_ns;
  p.pose.position = {x, 0.002, -0.003};
  p.pose.orientation = {std::cos(0.1), std::sin(0.1), 0, 0};
  p.pose.buttons = 1;
  return p;
}

UdpDeviceConfig loopback_config(const ManualClock& clock) {
  UdpDeviceConfig c;
  c.port = 0;
  c.clock = clock.clock();
  return c;
}

}  // namespace

TEST(HapticsUdp, BindsLoopbackOnAnEphemeralPortAndRejectsBadConfig) {
  ManualClock clock;
  UdpDevice device(loopback_config(clock));
  EXPECT_EQ(device.state(), DeviceState::closed);
  device.open();
  EXPECT_NE(device.bound_port(), 0);
  EXPECT_EQ(device.state(), DeviceState::lost);  // nothing received yet
  std::printf("udp device bound 127.0.0.1:%u\n", device.bound_port());

  UdpDeviceConfig bad = loopback_config(clock);
  bad.address = "localhost";
  EXPECT_THROW(UdpDevice{bad}, std::invalid_argument);
  bad = loopback_config(clock);
  bad.port = device.bound_port();  // taken
  UdpDevice clash(bad);
  try {
    clash.open();
    FAIL() << "binding a port in use must fail";
  } catch (const std::system_error& e) {
    EXPECT_NE(std::string(e.what()).find("bind"), std::string::npos) << e.what();
  }
}

TEST(HapticsUdp, PoseInForceOutRoundTrip) {
  ManualClock clock(1000 * kMs);
  UdpDevice device(loopback_config(clock));
  device.open();
  Sender sender(device.bound_port());

  sender.send_pose(pose_packet(1, 5 * kMs, 0.01));
  pump(device, 1);
  const DevicePose pose = device.read_pose();
  EXPECT_EQ(device.state(), DeviceState::ok);
  EXPECT_EQ(pose.position, (Vector3{0.01, 0.002, -0.003}));
  EXPECT_NEAR(pose.orientation[0], std::cos(0.1), 1e-15);
  EXPECT_NEAR(pose.orientation[1], std::sin(0.1), 1e-15);
  EXPECT_EQ(pose.buttons, 1u);

  device.write_force({0.25, -0.5, 1.0});
  const auto force = sender.receive_force();
  ASSERT_TRUE(force.has_value());
  EXPECT_EQ(force->state, DeviceState::ok);
  EXPECT_EQ(force->session, 77u);
  EXPECT_EQ(force->pose_sequence, 1u);
  EXPECT_EQ(force->sequence, 1u);
  EXPECT_EQ(force->timestamp_ns, 1000 * kMs);
  EXPECT_EQ(force->force, (Vector3{0.25, -0.5, 1.0}));

  // A second pose moves the device; the force answers it.
  sender.send_pose(pose_packet(2, 6 * kMs, 0.02));
  pump(device, 1);
  EXPECT_EQ(device.read_pose().position[0], 0.02);
  device.write_force({0, 0, 0.1});
  const auto second = sender.receive_force();
  ASSERT_TRUE(second.has_value());
  EXPECT_EQ(second->pose_sequence, 2u);
  EXPECT_EQ(device.statistics().accepted, 2u);
  EXPECT_EQ(device.statistics().dropped_total(), 0u);
}

TEST(HapticsUdp, DropsAndCountsEachBadPacketKind) {
  ManualClock clock(0);
  UdpDevice device(loopback_config(clock));
  device.open();
  Sender sender(device.bound_port());
  sender.send_pose(pose_packet(10, 100 * kMs, 0.01));
  pump(device, 1);
  ASSERT_EQ(device.statistics().accepted, 1u);

  auto send_modified = [&](auto modify) {
    auto b = protocol::encode(pose_packet(11, 101 * kMs, 0.05));
    std::vector<std::uint8_t> bytes(b.begin(), b.end());
    modify(bytes);
    sender.send_bytes(bytes.data(), bytes.size());
    pump(device, 1);
  };
  auto reseal = [](std::vector<std::uint8_t>& b) {
    const std::uint32_t crc = protocol::crc32(b.data(), b.size() - 4);
    for (int i = 0; i < 4; ++i) b[b.size() - 4 + i] = static_cast<std::uint8_t>(crc >> (8 * i));
  };
  auto put_f64 = [](std::vector<std::uint8_t>& b, std::size_t at, double v) {
    std::uint64_t bits;
    std::memcpy(&bits, &v, 8);
    for (int i = 0; i < 8; ++i) b[at + i] = static_cast<std::uint8_t>(bits >> (8 * i));
  };

  send_modified([](auto& b) { b[0] = 'X'; });
  send_modified([&](auto& b) { b[4] = 9; reseal(b); });
  send_modified([&](auto& b) { b[5] = 7; reseal(b); });
  send_modified([](auto& b) { b.resize(60); });
  send_modified([](auto& b) { b[33] ^= 0x10; });
  send_modified([&](auto& b) { put_f64(b, 32, std::nan("")); reseal(b); });
  send_modified([&](auto& b) { put_f64(b, 56, 2.0); reseal(b); });
  send_modified([](auto& b) { b.resize(1400, 0xAB); });                 // oversize
  sender.send_pose(pose_packet(10, 100 * kMs, 0.05));                  // replayed: 10 again
  pump(device, 1);
  sender.send_pose(pose_packet(12, 70 * kMs, 0.05));                   // stale: 30 ms behind the newest
  pump(device, 1);
  sender.send_pose(pose_packet(13, 5 * kMs, 0.05, /*session=*/78));    // foreign session while live
  pump(device, 1);
  sender.send_pose(pose_packet(20, 110 * kMs, 0.02));                  // accepted, jumps ahead
  pump(device, 1);
  sender.send_pose(pose_packet(15, 111 * kMs, 0.05));                  // out of order: never seen, lower
  pump(device, 1);
  sender.send_pose(pose_packet(20, 110 * kMs, 0.05));                  // replayed: 20 again
  pump(device, 1);

  const UdpStatistics s = device.statistics();
  for (std::size_t v = 1; v < protocol::kVerdictCount; ++v)
    std::printf("dropped %-20s %llu\n", protocol::to_string(static_cast<Verdict>(v)),
                static_cast<unsigned long long>(s.dropped[v]));
  EXPECT_EQ(s.dropped_for(Verdict::bad_magic), 1u);
  EXPECT_EQ(s.dropped_for(Verdict::bad_version), 1u);
  EXPECT_EQ(s.dropped_for(Verdict::bad_type), 1u);
  EXPECT_EQ(s.dropped_for(Verdict::bad_length), 1u);
  EXPECT_EQ(s.dropped_for(Verdict::bad_checksum), 1u);
  EXPECT_EQ(s.dropped_for(Verdict::non_finite), 1u);
  EXPECT_EQ(s.dropped_for(Verdict::non_unit_quaternion), 1u);
  EXPECT_EQ(s.dropped_for(Verdict::oversize), 1u);
  EXPECT_EQ(s.dropped_for(Verdict::stale), 1u);
  EXPECT_EQ(s.dropped_for(Verdict::foreign_session), 1u);
  EXPECT_EQ(s.dropped_for(Verdict::out_of_order), 1u);
  EXPECT_EQ(s.dropped_for(Verdict::replayed), 2u);
  EXPECT_EQ(s.dropped_total(), 13u);
  EXPECT_EQ(s.accepted, 2u);
  EXPECT_EQ(s.received, 15u);
  // Nothing dropped moved the device: it sits where the last accepted packet put it.
  EXPECT_EQ(device.read_pose().position[0], 0.02);
  EXPECT_EQ(device.last_pose_sequence(), 20u);
}

TEST(HapticsUdp, LossGivesZeroForceWithin50msAndRecovers) {
  ManualClock clock(0);
  UdpDevice device(loopback_config(clock));
  device.open();
  Sender sender(device.bound_port());
  const Vector3 push{1.0, 0, 0};

  clock.set_ns(10 * kMs);
  sender.send_pose(pose_packet(1, 0, 0.01));
  pump(device, 1);  // received at t = 10 ms by the device's clock
  ASSERT_EQ(device.state(), DeviceState::ok);
  device.write_force(push);
  EXPECT_EQ(sender.receive_force()->force, push);

  clock.set_ns(10 * kMs + 50 * kMs - 1);  // 1 ns short of 50 ms since the last packet
  device.read_pose();
  EXPECT_EQ(device.state(), DeviceState::ok);
  device.write_force(push);
  EXPECT_EQ(sender.receive_force()->force, push);

  clock.set_ns(10 * kMs + 50 * kMs);  // 50 ms without a valid packet: lost, zero force
  device.read_pose();
  EXPECT_EQ(device.state(), DeviceState::lost);
  device.write_force(push);
  auto lost = sender.receive_force();
  ASSERT_TRUE(lost.has_value());
  EXPECT_EQ(lost->state, DeviceState::lost);
  EXPECT_EQ(lost->force, (Vector3{0, 0, 0}));

  // Invalid packets do not bring it back.
  clock.set_ns(200 * kMs);
  auto bad = protocol::encode(pose_packet(2, 1 * kMs, 0.02));
  bad[40] ^= 1;
  sender.send_bytes(bad.data(), bad.size());
  pump(device, 1);
  EXPECT_EQ(device.state(), DeviceState::lost);
  EXPECT_EQ(device.read_pose().position[0], 0.01);  // last good pose held

  // A valid packet does.
  sender.send_pose(pose_packet(3, 2 * kMs, 0.03));
  pump(device, 1);
  EXPECT_EQ(device.state(), DeviceState::ok);
  EXPECT_EQ(device.read_pose().position[0], 0.03);
  device.write_force(push);
  auto back = sender.receive_force();
  ASSERT_TRUE(back.has_value());
  EXPECT_EQ(back->state, DeviceState::ok);
  EXPECT_EQ(back->force, push);
  EXPECT_EQ(device.statistics().losses, 1u);
}

TEST(HapticsUdp, ANewSessionTakesOverOnlyWhenTheOldOneIsLost) {
  ManualClock clock(0);
  UdpDevice device(loopback_config(clock));
  device.open();
  Sender sender(device.bound_port());
  sender.send_pose(pose_packet(500, 0, 0.01, 1));
  pump(device, 1);
  sender.send_pose(pose_packet(1, 0, 0.02, 2));  // a restarted bridge, while the first is live
  pump(device, 1);
  EXPECT_EQ(device.statistics().dropped_for(Verdict::foreign_session), 1u);
  clock.set_ns(60 * kMs);
  device.read_pose();
  ASSERT_EQ(device.state(), DeviceState::lost);
  sender.send_pose(pose_packet(1, 0, 0.02, 2));  // now it takes over, sequence from 1
  pump(device, 1);
  EXPECT_EQ(device.state(), DeviceState::ok);
  EXPECT_EQ(device.read_pose().position[0], 0.02);
  EXPECT_EQ(device.statistics().sessions, 2u);
}

// The real bridge program against the device, as an engine would run it: a "haptic thread"
// here reads the pose and answers with a spring force towards the origin.
TEST(HapticsUdp, BridgeProgramRoundTrip) {
  UdpDeviceConfig config;
  config.port = 0;
  UdpDevice device(config);
  device.open();
  const std::string command = std::string(INCISE_BRIDGE_PATH) + " --device 127.0.0.1:" +
                              std::to_string(device.bound_port()) +
                              " --script circle --radius 0.02 --period 0.5 --rate 500 --duration 0.6 --print-every 60";
  std::atomic<bool> done{false};
  std::vector<DevicePose> poses;
  std::uint64_t previous_sequence = 0;
  std::thread haptic([&] {
    while (!done.load()) {
      const DevicePose pose = device.read_pose();
      if (device.last_pose_sequence() != previous_sequence) {
        previous_sequence = device.last_pose_sequence();
        poses.push_back(pose);
        device.write_force({-50 * pose.position[0], -50 * pose.position[1], -50 * pose.position[2]});
      }
      std::this_thread::sleep_for(std::chrono::microseconds(500));
    }
  });
  FILE* bridge = popen(command.c_str(), "r");
  ASSERT_NE(bridge, nullptr);
  std::string output;
  char line[512];
  while (std::fgets(line, sizeof line, bridge)) output += line;
  const int status = pclose(bridge);
  done.store(true);
  haptic.join();
  std::printf("%s", output.c_str());

  EXPECT_EQ(status, 0);
  const UdpStatistics s = device.statistics();
  std::printf("device: accepted %llu, dropped %llu, forces sent %llu\n", static_cast<unsigned long long>(s.accepted),
              static_cast<unsigned long long>(s.dropped_total()), static_cast<unsigned long long>(s.forces_sent));
  EXPECT_GT(s.accepted, 50u);
  EXPECT_EQ(s.dropped_total(), 0u);
  ASSERT_FALSE(poses.empty());
  for (const DevicePose& p : poses) EXPECT_NEAR(std::hypot(p.position[0], p.position[1]), 0.02, 1e-12);
  EXPECT_NE(output.find("state=ok"), std::string::npos);
  const auto summary = output.find("received ");
  ASSERT_NE(summary, std::string::npos);
  EXPECT_GT(std::stol(output.substr(summary + 9)), 0);
  EXPECT_NE(output.find("max |f| 1.0000 N"), std::string::npos) << "50 N/m at 2 cm";
}
