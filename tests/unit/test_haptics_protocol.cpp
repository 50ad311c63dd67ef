// The wire format of docs/haptics-protocol.md: CRC-32, the byte layout, and the structural
// checks each malformed packet kind fails.
#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <limits>
#include <vector>

#include "haptics/udp_protocol.hpp"

namespace protocol = incise::haptics::protocol;
using protocol::Verdict;

namespace {

protocol::PosePacket sample_pose() {
  protocol::PosePacket p;
  p.session = 0xA1B2C3D4;
  p.sequence = 0x0102030405060708ull;
  p.timestamp_ns = 123'456'789'012;
  p.pose.position = {0.01, -0.02, 0.03};
  const double h = std::sqrt(0.5);
  p.pose.orientation = {h, 0, h, 0};
  p.pose.buttons = 5;
  return p;
}

void reseal(std::uint8_t* bytes, std::size_t size) {
  const std::uint32_t crc = protocol::crc32(bytes, size - 4);
  for (int i = 0; i < 4; ++i) bytes[size - 4 + i] = static_cast<std::uint8_t>(crc >> (8 * i));
}

void put_f64(std::uint8_t* p, double v) {
  std::uint64_t bits;
  std::memcpy(&bits, &v, 8);
  for (int i = 0; i < 8; ++i) p[i] = static_cast<std::uint8_t>(bits >> (8 * i));
}

}  // namespace

TEST(HapticsProtocol, Crc32MatchesTheStandardCheckValue) {
  const char* text = "123456789";
  EXPECT_EQ(protocol::crc32(reinterpret_cast<const std::uint8_t*>(text), 9), 0xCBF43926u);
  EXPECT_EQ(protocol::crc32(nullptr, 0), 0u);
}

TEST(HapticsProtocol, PosePacketLayoutIsLittleEndianAsDocumented) {
  const auto b = protocol::encode(sample_pose());
  ASSERT_EQ(b.size(), 92u);
  EXPECT_EQ(std::string(reinterpret_cast<const char*>(b.data()), 4), "INCH");
  EXPECT_EQ(b[4], 1);  // version
  EXPECT_EQ(b[5], 1);  // type pose
  EXPECT_EQ(b[6] | (b[7] << 8), 92);
  EXPECT_EQ(b[8], 0xD4);   // session, low byte first
  EXPECT_EQ(b[11], 0xA1);
  EXPECT_EQ(b[12], 5);     // buttons
  EXPECT_EQ(b[16], 0x08);  // sequence
  EXPECT_EQ(b[23], 0x01);
  double x;
  std::memcpy(&x, &b[32], 8);  // the host is little-endian here (x86-64)
  EXPECT_EQ(x, 0.01);
  const std::uint32_t crc = b[88] | (b[89] << 8) | (b[90] << 16) | (std::uint32_t{b[91]} << 24);
  EXPECT_EQ(crc, protocol::crc32(b.data(), 88));
}

TEST(HapticsProtocol, PoseAndForceRoundTrip) {
  const protocol::PosePacket in = sample_pose();
  const auto bytes = protocol::encode(in);
  protocol::PosePacket out;
  ASSERT_EQ(protocol::decode_pose(bytes.data(), bytes.size(), out), Verdict::accepted);
  EXPECT_EQ(out.session, in.session);
  EXPECT_EQ(out.sequence, in.sequence);
  EXPECT_EQ(out.timestamp_ns, in.timestamp_ns);
  EXPECT_EQ(out.pose.position, in.pose.position);
  for (int i = 0; i < 4; ++i) EXPECT_NEAR(out.pose.orientation[i], in.pose.orientation[i], 1e-15);
  EXPECT_EQ(out.pose.buttons, in.pose.buttons);

  protocol::ForcePacket f;
  f.session = 7;
  f.state = incise::haptics::DeviceState::lost;
  f.sequence = 99;
  f.pose_sequence = 42;
  f.timestamp_ns = -5;
  f.force = {0.5, -1.25, 2};
  const auto fb = protocol::encode(f);
  ASSERT_EQ(fb.size(), 68u);
  protocol::ForcePacket g;
  ASSERT_EQ(protocol::decode_force(fb.data(), fb.size(), g), Verdict::accepted);
  EXPECT_EQ(g.session, 7u);
  EXPECT_EQ(g.state, incise::haptics::DeviceState::lost);
  EXPECT_EQ(g.sequence, 99u);
  EXPECT_EQ(g.pose_sequence, 42u);
  EXPECT_EQ(g.timestamp_ns, -5);
  EXPECT_EQ(g.force, f.force);
}

TEST(HapticsProtocol, EachMalformedKindIsNamed) {
  const auto good = protocol::encode(sample_pose());
  protocol::PosePacket out;
  auto verdict = [&](std::vector<std::uint8_t> b, std::size_t size) {
    b.resize(std::max<std::size_t>(b.size(), protocol::kPoseSize + 1));
    return protocol::decode_pose(b.data(), size, out);
  };
  std::vector<std::uint8_t> b(good.begin(), good.end());

  EXPECT_EQ(verdict(b, 92), Verdict::accepted);
  EXPECT_EQ(verdict(b, 93), Verdict::oversize);
  EXPECT_EQ(verdict(b, 91), Verdict::bad_length);
  EXPECT_EQ(verdict(b, 3), Verdict::bad_length);

  auto m = b;
  m[0] ^= 0xFF;
  EXPECT_EQ(verdict(m, 92), Verdict::bad_magic);
  m = b;
  m[4] = 2;
  reseal(m.data(), 92);
  EXPECT_EQ(verdict(m, 92), Verdict::bad_version);
  m = b;
  m[5] = protocol::kTypeForce;
  reseal(m.data(), 92);
  EXPECT_EQ(verdict(m, 92), Verdict::bad_type);
  m = b;
  m[6] = 91;
  reseal(m.data(), 92);
  EXPECT_EQ(verdict(m, 92), Verdict::bad_length);
  m = b;
  m[40] ^= 0x01;  // a bit of position y
  EXPECT_EQ(verdict(m, 92), Verdict::bad_checksum);
  m = b;
  put_f64(&m[40], std::numeric_limits<double>::quiet_NaN());
  reseal(m.data(), 92);
  EXPECT_EQ(verdict(m, 92), Verdict::non_finite);
  m = b;
  put_f64(&m[56], std::numeric_limits<double>::infinity());
  reseal(m.data(), 92);
  EXPECT_EQ(verdict(m, 92), Verdict::non_finite);
  m = b;
  put_f64(&m[56], 0.9);
  put_f64(&m[64], 0.0);
  put_f64(&m[72], 0.0);
  put_f64(&m[80], 0.0);
  reseal(m.data(), 92);
  EXPECT_EQ(verdict(m, 92), Verdict::non_unit_quaternion);
  // Within tolerance: accepted and normalised.
  put_f64(&m[56], 1.0005);
  reseal(m.data(), 92);
  ASSERT_EQ(verdict(m, 92), Verdict::accepted);
  EXPECT_DOUBLE_EQ(out.pose.orientation[0], 1.0);
}
