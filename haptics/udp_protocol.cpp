#include "haptics/udp_protocol.hpp"

#include <bit>
#include <cmath>

namespace incise::haptics::protocol {

const char* to_string(Verdict v) {
  switch (v) {
    case Verdict::accepted: return "accepted";
    case Verdict::oversize: return "oversize";
    case Verdict::bad_length: return "bad_length";
    case Verdict::bad_magic: return "bad_magic";
    case Verdict::bad_version: return "bad_version";
    case Verdict::bad_type: return "bad_type";
    case Verdict::bad_checksum: return "bad_checksum";
    case Verdict::non_finite: return "non_finite";
    case Verdict::non_unit_quaternion: return "non_unit_quaternion";
    case Verdict::foreign_session: return "foreign_session";
    case Verdict::replayed: return "replayed";
    case Verdict::out_of_order: return "out_of_order";
    case Verdict::stale: return "stale";
    case Verdict::count_: break;
  }
  return "?";
}

namespace {

constexpr std::array<std::uint32_t, 256> make_crc_table() {
  std::array<std::uint32_t, 256> table{};
  for (std::uint32_t i = 0; i < 256; ++i) {
    std::uint32_t c = i;
    for (int k = 0; k < 8; ++k) c = (c & 1) ? 0xEDB88320u ^ (c >> 1) : c >> 1;
    table[i] = c;
  }
  return table;
}
constexpr auto kCrcTable = make_crc_table();

// Explicit little-endian access, whatever the host's byte order.
void put_u16(std::uint8_t* p, std::uint16_t v) {
  p[0] = static_cast<std::uint8_t>(v);
  p[1] = static_cast<std::uint8_t>(v >> 8);
}
void put_u32(std::uint8_t* p, std::uint32_t v) {
  for (int i = 0; i < 4; ++i) p[i] = static_cast<std::uint8_t>(v >> (8 * i));
}
void put_u64(std::uint8_t* p, std::uint64_t v) {
  for (int i = 0; i < 8; ++i) p[i] = static_cast<std::uint8_t>(v >> (8 * i));
}
void put_f64(std::uint8_t* p, double v) { put_u64(p, std::bit_cast<std::uint64_t>(v)); }
std::uint16_t get_u16(const std::uint8_t* p) { return static_cast<std::uint16_t>(p[0] | (p[1] << 8)); }
std::uint32_t get_u32(const std::uint8_t* p) {
  std::uint32_t v = 0;
  for (int i = 0; i < 4; ++i) v |= std::uint32_t{p[i]} << (8 * i);
  return v;
}
std::uint64_t get_u64(const std::uint8_t* p) {
  std::uint64_t v = 0;
  for (int i = 0; i < 8; ++i) v |= std::uint64_t{p[i]} << (8 * i);
  return v;
}
double get_f64(const std::uint8_t* p) { return std::bit_cast<double>(get_u64(p)); }

void put_header(std::uint8_t* p, std::uint8_t type, std::size_t size) {
  put_u32(p, kMagic);
  p[4] = kVersion;
  p[5] = type;
  put_u16(p + 6, static_cast<std::uint16_t>(size));
}

void seal(std::uint8_t* p, std::size_t size) { put_u32(p + size - 4, crc32(p, size - 4)); }

Verdict check_frame(const std::uint8_t* data, std::size_t size, std::uint8_t type, std::size_t expected) {
  if (size > expected) return Verdict::oversize;
  if (size < 8) return Verdict::bad_length;
  if (get_u32(data) != kMagic) return Verdict::bad_magic;
  if (data[4] != kVersion) return Verdict::bad_version;
  if (data[5] != type) return Verdict::bad_type;
  if (size != expected || get_u16(data + 6) != expected) return Verdict::bad_length;
  if (get_u32(data + expected - 4) != crc32(data, expected - 4)) return Verdict::bad_checksum;
  return Verdict::accepted;
}

}  // namespace

std::uint32_t crc32(const std::uint8_t* data, std::size_t size) {
  std::uint32_t c = 0xFFFFFFFFu;
  for (std::size_t i = 0; i < size; ++i) c = kCrcTable[(c ^ data[i]) & 0xFF] ^ (c >> 8);
  return c ^ 0xFFFFFFFFu;
}

std::array<std::uint8_t, kPoseSize> encode(const PosePacket& packet) {
  std::array<std::uint8_t, kPoseSize> b{};
  put_header(b.data(), kTypePose, kPoseSize);
  put_u32(&b[8], packet.session);
  put_u32(&b[12], packet.pose.buttons);
  put_u64(&b[16], packet.sequence);
  put_u64(&b[24], static_cast<std::uint64_t>(packet.timestamp_ns));
  for (int i = 0; i < 3; ++i) put_f64(&b[32 + 8 * i], packet.pose.position[i]);
  for (int i = 0; i < 4; ++i) put_f64(&b[56 + 8 * i], packet.pose.orientation[i]);
  seal(b.data(), kPoseSize);
  return b;
}

std::array<std::uint8_t, kForceSize> encode(const ForcePacket& packet) {
  std::array<std::uint8_t, kForceSize> b{};
  put_header(b.data(), kTypeForce, kForceSize);
  put_u32(&b[8], packet.session);
  b[12] = static_cast<std::uint8_t>(packet.state);
  put_u64(&b[16], packet.sequence);
  put_u64(&b[24], packet.pose_sequence);
  put_u64(&b[32], static_cast<std::uint64_t>(packet.timestamp_ns));
  for (int i = 0; i < 3; ++i) put_f64(&b[40 + 8 * i], packet.force[i]);
  seal(b.data(), kForceSize);
  return b;
}

Verdict decode_pose(const std::uint8_t* data, std::size_t size, PosePacket& out, double quaternion_tolerance) {
  if (const Verdict v = check_frame(data, size, kTypePose, kPoseSize); v != Verdict::accepted) return v;
  PosePacket p;
  p.session = get_u32(data + 8);
  p.pose.buttons = get_u32(data + 12);
  p.sequence = get_u64(data + 16);
  p.timestamp_ns = static_cast<std::int64_t>(get_u64(data + 24));
  for (int i = 0; i < 3; ++i) p.pose.position[i] = get_f64(data + 32 + 8 * i);
  for (int i = 0; i < 4; ++i) p.pose.orientation[i] = get_f64(data + 56 + 8 * i);
  for (double v : p.pose.position)
    if (!std::isfinite(v)) return Verdict::non_finite;
  for (double v : p.pose.orientation)
    if (!std::isfinite(v)) return Verdict::non_finite;
  const double n = quaternion_norm(p.pose.orientation);
  if (!(std::abs(n - 1) <= quaternion_tolerance)) return Verdict::non_unit_quaternion;
  for (double& q : p.pose.orientation) q /= n;
  out = p;
  return Verdict::accepted;
}

Verdict decode_force(const std::uint8_t* data, std::size_t size, ForcePacket& out) {
  if (const Verdict v = check_frame(data, size, kTypeForce, kForceSize); v != Verdict::accepted) return v;
  ForcePacket p;
  p.session = get_u32(data + 8);
  const std::uint8_t state = data[12];
  if (state != static_cast<std::uint8_t>(DeviceState::ok) && state != static_cast<std::uint8_t>(DeviceState::lost))
    return Verdict::bad_type;
  p.state = static_cast<DeviceState>(state);
  p.sequence = get_u64(data + 16);
  p.pose_sequence = get_u64(data + 24);
  p.timestamp_ns = static_cast<std::int64_t>(get_u64(data + 32));
  for (int i = 0; i < 3; ++i) {
    p.force[i] = get_f64(data + 40 + 8 * i);
    if (!std::isfinite(p.force[i])) return Verdict::non_finite;
  }
  out = p;
  return Verdict::accepted;
}

}  // namespace incise::haptics::protocol
