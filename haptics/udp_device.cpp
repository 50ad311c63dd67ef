#include "haptics/udp_device.hpp"

#include <arpa/inet.h>
#include <cerrno>
#include <cstring>
#include <sys/socket.h>
#include <system_error>
#include <unistd.h>

namespace incise::haptics {

using protocol::Verdict;

UdpDevice::UdpDevice(UdpDeviceConfig config) : config_(std::move(config)) {
  validate_limits(config_.limits, "udp device limits");
  in_addr probe{};
  if (inet_pton(AF_INET, config_.address.c_str(), &probe) != 1)
    throw std::invalid_argument("udp device: address '" + config_.address + "' is not an IPv4 dotted quad");
  if (config_.loss_timeout_ns <= 0) throw std::invalid_argument("udp device: loss_timeout_ns must be > 0");
  if (config_.stale_after_ns <= 0) throw std::invalid_argument("udp device: stale_after_ns must be > 0");
  require_finite(config_.quaternion_tolerance, "udp device quaternion_tolerance");
  if (config_.max_packets_per_read < 1) throw std::invalid_argument("udp device: max_packets_per_read must be >= 1");
  if (!config_.clock) throw std::invalid_argument("udp device: no clock");
}

UdpDevice::~UdpDevice() { close(); }

void UdpDevice::open() {
  if (socket_ >= 0) return;
  const std::string where = "udp device " + config_.address + ":" + std::to_string(config_.port);
  const int fd = ::socket(AF_INET, SOCK_DGRAM | SOCK_NONBLOCK | SOCK_CLOEXEC, 0);
  if (fd < 0) throw std::system_error(errno, std::generic_category(), where + ": socket");
  sockaddr_in address{};
  address.sin_family = AF_INET;
  address.sin_port = htons(config_.port);
  inet_pton(AF_INET, config_.address.c_str(), &address.sin_addr);
  if (::bind(fd, reinterpret_cast<const sockaddr*>(&address), sizeof address) != 0) {
    const int error = errno;
    ::close(fd);
    throw std::system_error(error, std::generic_category(), where + ": bind");
  }
  socklen_t length = sizeof address;
  getsockname(fd, reinterpret_cast<sockaddr*>(&address), &length);
  socket_ = fd;
  bound_port_.store(ntohs(address.sin_port), std::memory_order_release);
  has_pose_ = has_peer_ = false;
  last_sequence_ = seen_window_ = 0;
  state_.store(DeviceState::lost, std::memory_order_release);  // until the first valid pose
}

void UdpDevice::close() {
  if (socket_ >= 0) ::close(socket_);
  socket_ = -1;
  state_.store(DeviceState::closed, std::memory_order_release);
}

void UdpDevice::receive_one(const std::uint8_t* data, std::size_t size, const sockaddr_in& from, std::int64_t now) {
  protocol::PosePacket packet;
  const Verdict structural = protocol::decode_pose(data, size, packet, config_.quaternion_tolerance);
  if (structural != Verdict::accepted) return count(structural);

  const bool new_session = !has_pose_ || packet.session != session_;
  if (new_session) {
    if (has_pose_ && live(now)) return count(Verdict::foreign_session);
    // Take over: the history of the previous session says nothing about this one.
    session_ = packet.session;
    last_sequence_ = 0;
    seen_window_ = 0;
    newest_timestamp_ns_ = packet.timestamp_ns;
    sessions_.fetch_add(1, std::memory_order_relaxed);
  } else if (packet.sequence <= last_sequence_) {
    const std::uint64_t behind = last_sequence_ - packet.sequence;
    const bool seen = behind < 64 && ((seen_window_ >> behind) & 1);
    return count(seen ? Verdict::replayed : Verdict::out_of_order);
  } else if (packet.timestamp_ns < newest_timestamp_ns_ - config_.stale_after_ns) {
    return count(Verdict::stale);
  }

  if (new_session) {
    seen_window_ = 1;
  } else {
    const std::uint64_t ahead = packet.sequence - last_sequence_;
    seen_window_ = (ahead >= 64 ? 0 : seen_window_ << ahead) | 1;
  }
  last_sequence_ = packet.sequence;
  if (packet.timestamp_ns > newest_timestamp_ns_) newest_timestamp_ns_ = packet.timestamp_ns;
  pose_ = packet.pose;
  has_pose_ = true;
  last_valid_ns_ = now;
  peer_ = from;
  has_peer_ = true;
  accepted_.fetch_add(1, std::memory_order_relaxed);
}

DevicePose UdpDevice::read_pose() {
  if (socket_ < 0) return pose_;
  const std::int64_t now = config_.clock();
  // One byte more than the largest packet: with MSG_TRUNC recvfrom returns the real length, so
  // an oversize datagram is seen as such and never parsed.
  std::uint8_t buffer[protocol::kPoseSize + 1];
  for (int i = 0; i < config_.max_packets_per_read; ++i) {
    sockaddr_in from{};
    socklen_t from_length = sizeof from;
    const ssize_t n = ::recvfrom(socket_, buffer, sizeof buffer, MSG_DONTWAIT | MSG_TRUNC,
                                 reinterpret_cast<sockaddr*>(&from), &from_length);
    if (n < 0) break;  // EAGAIN: nothing more; any other error: try again next tick
    received_.fetch_add(1, std::memory_order_relaxed);
    receive_one(buffer, static_cast<std::size_t>(n), from, now);
  }
  const DeviceState next = live(now) ? DeviceState::ok : DeviceState::lost;
  if (next == DeviceState::lost && state_.load(std::memory_order_relaxed) == DeviceState::ok)
    losses_.fetch_add(1, std::memory_order_relaxed);
  state_.store(next, std::memory_order_release);
  return pose_;
}

void UdpDevice::write_force(const Vector3& force) {
  if (socket_ < 0 || !has_peer_) return;
  protocol::ForcePacket packet;
  packet.session = session_;
  packet.state = state();
  packet.sequence = ++force_sequence_;
  packet.pose_sequence = last_sequence_;
  packet.timestamp_ns = config_.clock();
  if (packet.state == DeviceState::ok)
    for (int i = 0; i < 3; ++i) packet.force[i] = std::isfinite(force[i]) ? force[i] : 0.0;
  const auto bytes = protocol::encode(packet);
  const ssize_t n = ::sendto(socket_, bytes.data(), bytes.size(), MSG_DONTWAIT | MSG_NOSIGNAL,
                             reinterpret_cast<const sockaddr*>(&peer_), sizeof peer_);
  if (n == static_cast<ssize_t>(bytes.size()))
    forces_sent_.fetch_add(1, std::memory_order_relaxed);
  else
    send_errors_.fetch_add(1, std::memory_order_relaxed);
}

UdpStatistics UdpDevice::statistics() const {
  UdpStatistics s;
  s.received = received_.load(std::memory_order_relaxed);
  s.accepted = accepted_.load(std::memory_order_relaxed);
  for (std::size_t i = 0; i < s.dropped.size(); ++i) s.dropped[i] = dropped_[i].load(std::memory_order_relaxed);
  s.forces_sent = forces_sent_.load(std::memory_order_relaxed);
  s.send_errors = send_errors_.load(std::memory_order_relaxed);
  s.sessions = sessions_.load(std::memory_order_relaxed);
  s.losses = losses_.load(std::memory_order_relaxed);
  return s;
}

}  // namespace incise::haptics
