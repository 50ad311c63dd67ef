// A datagram -> decode_pose and decode_force (haptics/udp_protocol.hpp), as UdpDevice calls
// them: the buffer holds at most its capacity, `size` is the datagram's real length. What is
// accepted must be finite with a unit quaternion, and encode it back to the same fields.
#include "haptics/udp_protocol.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <cstring>

namespace protocol = incise::haptics::protocol;

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  // A datagram longer than the buffer arrives truncated to it (recvfrom with MSG_TRUNC), its
  // real length told: the smallest capacity the decoder allows.
  const std::size_t claimed = size;
  std::array<std::uint8_t, protocol::kPoseSize> buffer{};
  std::memcpy(buffer.data(), data, std::min(size, buffer.size()));

  protocol::PosePacket pose;
  if (protocol::decode_pose(buffer.data(), claimed, pose) == protocol::Verdict::accepted) {
    for (double v : pose.pose.position)
      if (!std::isfinite(v)) std::abort();
    if (!(std::abs(incise::haptics::quaternion_norm(pose.pose.orientation) - 1) <= 1e-9)) std::abort();
    protocol::PosePacket again;
    if (protocol::decode_pose(protocol::encode(pose).data(), protocol::kPoseSize, again) != protocol::Verdict::accepted ||
        again.sequence != pose.sequence || again.session != pose.session || again.pose.buttons != pose.pose.buttons)
      std::abort();
  }
  protocol::ForcePacket force;
  if (protocol::decode_force(buffer.data(), claimed, force) == protocol::Verdict::accepted) {
    for (double v : force.force)
      if (!std::isfinite(v)) std::abort();
  }
  return 0;
}
