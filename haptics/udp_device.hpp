// A device on the other end of a UDP socket: a bridge process (haptics/bridge/, or one written
// for a real device's SDK) sends pose packets and receives force packets, in the protocol of
// docs/haptics-protocol.md. Binds 127.0.0.1 unless configured otherwise (IPv4; port 0 picks an
// ephemeral port, reported by bound_port()).
//
// Every call on the hot path is non-blocking: read_pose() drains what the socket holds
// (recvfrom with MSG_DONTWAIT, at most max_packets_per_read datagrams), write_force() is one
// sendto with MSG_DONTWAIT to the sender of the newest accepted pose. Neither throws, neither
// allocates. Dropped packets are counted per protocol::Verdict; counters can be read from any
// thread (statistics()).
//
// Loss: when no valid pose has arrived for loss_timeout_ns (50 ms) by the device's clock,
// state() is `lost`, write_force() sends zero force (with state lost in the packet) whatever it
// is given, and read_pose() keeps returning the last good pose; the first valid packet after
// that makes it `ok` again. A new session id is accepted only when there is no live session
// (before the first packet or while lost), and resets the sequence and timestamp history, so a
// restarted bridge takes over without a restart of incise.
#pragma once

#include <array>
#include <atomic>
#include <cstdint>
#include <string>

#include <netinet/in.h>

#include "haptics/clock.hpp"
#include "haptics/device.hpp"
#include "haptics/udp_protocol.hpp"

namespace incise::haptics {

struct UdpDeviceConfig {
  std::string address = "127.0.0.1";  // IPv4 dotted quad to bind; "0.0.0.0" for every interface
  std::uint16_t port = protocol::kDefaultPort;  // 0: ephemeral
  DeviceLimits limits{};
  std::int64_t loss_timeout_ns = 50'000'000;
  std::int64_t stale_after_ns = 20'000'000;  // drop a pose older than the newest by more than this
  double quaternion_tolerance = kUnitQuaternionTolerance;
  int max_packets_per_read = 64;  // bounds the work of one tick under a flood
  Clock clock = monotonic_clock();
};

struct UdpStatistics {
  std::uint64_t received = 0;  // datagrams read
  std::uint64_t accepted = 0;
  std::array<std::uint64_t, protocol::kVerdictCount> dropped{};  // by Verdict; [accepted] unused
  std::uint64_t forces_sent = 0;
  std::uint64_t send_errors = 0;  // sendto failed (would block, peer gone): counted, not retried
  std::uint64_t sessions = 0;     // sessions taken over
  std::uint64_t losses = 0;       // ok -> lost transitions
  std::uint64_t dropped_total() const {
    std::uint64_t n = 0;
    for (std::size_t i = 1; i < dropped.size(); ++i) n += dropped[i];
    return n;
  }
  std::uint64_t dropped_for(protocol::Verdict v) const { return dropped[static_cast<std::size_t>(v)]; }
};

class UdpDevice final : public Device {
 public:
  explicit UdpDevice(UdpDeviceConfig config);  // validates; throws std::invalid_argument
  ~UdpDevice() override;
  UdpDevice(const UdpDevice&) = delete;
  UdpDevice& operator=(const UdpDevice&) = delete;

  std::uint16_t bound_port() const { return bound_port_.load(std::memory_order_acquire); }
  UdpStatistics statistics() const;
  std::uint64_t last_pose_sequence() const { return last_sequence_; }  // haptic thread

  std::string_view name() const override { return "udp"; }
  void open() override;  // socket + bind; std::system_error naming the address on failure
  void close() override;
  DevicePose read_pose() override;
  DeviceState state() const override { return state_.load(std::memory_order_acquire); }
  void write_force(const Vector3& force) override;
  DeviceLimits limits() const override { return config_.limits; }

 private:
  void receive_one(const std::uint8_t* data, std::size_t size, const sockaddr_in& from, std::int64_t now);
  void count(protocol::Verdict v) { dropped_[static_cast<std::size_t>(v)].fetch_add(1, std::memory_order_relaxed); }
  bool live(std::int64_t now) const { return has_pose_ && now - last_valid_ns_ < config_.loss_timeout_ns; }

  UdpDeviceConfig config_;
  int socket_ = -1;
  std::atomic<std::uint16_t> bound_port_{0};
  std::atomic<DeviceState> state_{DeviceState::closed};

  // Haptic-thread state.
  bool has_pose_ = false;
  bool has_peer_ = false;
  sockaddr_in peer_{};
  DevicePose pose_{};
  std::uint32_t session_ = 0;
  std::uint64_t last_sequence_ = 0;
  std::uint64_t seen_window_ = 0;  // bit i: sequence last_sequence_ - i was accepted
  std::int64_t newest_timestamp_ns_ = 0;
  std::int64_t last_valid_ns_ = 0;
  std::uint64_t force_sequence_ = 0;

  std::atomic<std::uint64_t> received_{0}, accepted_{0}, forces_sent_{0}, send_errors_{0}, sessions_{0}, losses_{0};
  std::array<std::atomic<std::uint64_t>, protocol::kVerdictCount> dropped_{};
};

}  // namespace incise::haptics
