// The incise haptic UDP protocol, version 1 (docs/haptics-protocol.md describes it byte by
// byte): a bridge process next to a real device sends pose packets, the UdpDevice answers each
// tick with a force packet. Little-endian, fixed size, CRC-32 at the end. Free functions over
// byte buffers, no sockets: the bridge, the device and the tests all use these.
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>

#include "haptics/device.hpp"

namespace incise::haptics::protocol {

inline constexpr std::uint32_t kMagic = 0x48434E49;  // bytes 'I' 'N' 'C' 'H'
inline constexpr std::uint8_t kVersion = 1;
inline constexpr std::uint8_t kTypePose = 1, kTypeForce = 2;
inline constexpr std::size_t kPoseSize = 92, kForceSize = 68;
inline constexpr std::uint16_t kDefaultPort = 47810;

struct PosePacket {
  std::uint32_t session = 0;       // chosen by the bridge per run; a new one resets the sequence
  std::uint64_t sequence = 0;      // increases by (at least) 1 per packet within a session
  std::int64_t timestamp_ns = 0;   // bridge's monotonic clock when the pose was read
  DevicePose pose;
};

struct ForcePacket {
  std::uint32_t session = 0;        // session of the newest accepted pose (0: none yet)
  DeviceState state = DeviceState::ok;
  std::uint64_t sequence = 0;       // the device's own, from 1
  std::uint64_t pose_sequence = 0;  // newest accepted pose sequence (for round-trip latency)
  std::int64_t timestamp_ns = 0;    // device clock
  Vector3 force{};                  // N, to apply to the hand
};

// Why a packet was dropped. `accepted` is not a drop. Order = order of the checks.
enum class Verdict : std::uint8_t {
  accepted = 0,
  oversize,             // datagram longer than the packet type allows
  bad_length,           // shorter, or the length field disagrees with the datagram
  bad_magic,
  bad_version,
  bad_type,
  bad_checksum,
  non_finite,           // NaN or infinity in position or orientation
  non_unit_quaternion,  // | |q| - 1 | beyond the tolerance
  foreign_session,      // another session while the current one is live
  replayed,             // a sequence already accepted
  out_of_order,         // a sequence lower than the newest accepted, not seen before
  stale,                // timestamp older than the newest accepted by more than the threshold
  count_
};
inline constexpr std::size_t kVerdictCount = static_cast<std::size_t>(Verdict::count_);
const char* to_string(Verdict v);

// CRC-32 (IEEE 802.3 / zlib: reflected, polynomial 0xEDB88320, init and final xor 0xFFFFFFFF).
// crc32("123456789") == 0xCBF43926.
std::uint32_t crc32(const std::uint8_t* data, std::size_t size);

std::array<std::uint8_t, kPoseSize> encode(const PosePacket& packet);
std::array<std::uint8_t, kForceSize> encode(const ForcePacket& packet);

// Structural checks only (length, magic, version, type, checksum, finite, unit quaternion);
// sequence, session and staleness need the receiver's history (UdpDevice). `size` is the
// datagram's real length (recvfrom with MSG_TRUNC), which may exceed the bytes in `data`
// when the datagram was truncated: data must hold min(size, capacity) bytes, capacity >= kPoseSize.
Verdict decode_pose(const std::uint8_t* data, std::size_t size, PosePacket& out,
                    double quaternion_tolerance = kUnitQuaternionTolerance);
Verdict decode_force(const std::uint8_t* data, std::size_t size, ForcePacket& out);

}  // namespace incise::haptics::protocol
