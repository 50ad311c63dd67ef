// incise-bridge: plays a scripted haptic device over the incise UDP protocol
// (docs/haptics-protocol.md) and prints the forces it receives. It is also the example to copy
// when writing a bridge for a real device: replace read_device_pose() and apply_force() with
// the SDK's calls (marked "REAL DEVICE" below) and keep the rest — the packet encoding,
// the session and sequence numbers, the absolute-deadline loop and the non-blocking socket.
//
//   incise-bridge [--device HOST:PORT] [--script circle|poke|still] [--center X,Y,Z]
//                 [--radius M] [--period S] [--rate HZ] [--duration S] [--session N]
//                 [--buttons N] [--print-every N] [--quiet]
//
// circle: the tool goes round a circle of --radius in the x-y plane about --center, one turn per
// --period. poke: it moves from --center down (-z) by --radius and back, once per --period, with
// the engage button held while below the centre. still: it stays at --center.
// Exit status: 0 after --duration, 2 on a usage error, 1 on a socket error.
#include "common/percentile.hpp"

#include <arpa/inet.h>
#include <netinet/in.h>
#include <sys/socket.h>
#include <time.h>
#include <unistd.h>

#include <algorithm>
#include <array>
#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <numbers>
#include <string>
#include <vector>

#include "haptics/clock.hpp"
#include "haptics/udp_protocol.hpp"

namespace {

using incise::haptics::DevicePose;
using incise::haptics::Vector3;
namespace protocol = incise::haptics::protocol;

struct Options {
  std::string host = "127.0.0.1";
  int port = protocol::kDefaultPort;
  std::string script = "circle";
  Vector3 center{0, 0, 0};
  double radius = 0.02;  // m
  double period = 2.0;   // s
  double rate = 1000;    // Hz
  double duration = 2.0; // s
  std::uint32_t session = 0;
  std::uint32_t buttons = 0;
  long print_every = 100;
  bool quiet = false;
};

[[noreturn]] void usage(const std::string& problem) {
  std::fprintf(stderr,
               "incise-bridge: %s\n"
               "usage: incise-bridge [--device HOST:PORT] [--script circle|poke|still] [--center X,Y,Z]\n"
               "                     [--radius M] [--period S] [--rate HZ] [--duration S] [--session N]\n"
               "                     [--buttons N] [--print-every N] [--quiet]\n",
               problem.c_str());
  std::exit(2);
}

double parse_number(const std::string& flag, const std::string& text) {
  char* end = nullptr;
  const double v = std::strtod(text.c_str(), &end);
  if (text.empty() || *end != '\0' || !std::isfinite(v)) usage(flag + ": '" + text + "' is not a number");
  return v;
}

Options parse(int argc, char** argv) {
  Options o;
  for (int i = 1; i < argc; ++i) {
    const std::string flag = argv[i];
    if (flag == "--quiet") {
      o.quiet = true;
      continue;
    }
    if (flag == "--help" || flag == "-h") usage("plays a scripted device over the incise haptic protocol");
    if (i + 1 >= argc) usage(flag + " needs a value");
    const std::string value = argv[++i];
    if (flag == "--device") {
      const auto colon = value.rfind(':');
      if (colon == std::string::npos) usage("--device: expected HOST:PORT, got '" + value + "'");
      o.host = value.substr(0, colon);
      o.port = static_cast<int>(parse_number(flag, value.substr(colon + 1)));
      if (o.port < 1 || o.port > 65535) usage("--device: port out of range");
    } else if (flag == "--script") {
      if (value != "circle" && value != "poke" && value != "still") usage("--script: circle, poke or still");
      o.script = value;
    } else if (flag == "--center") {
      std::size_t start = 0;
      for (int k = 0; k < 3; ++k) {
        const std::size_t comma = value.find(',', start);
        if ((k < 2) == (comma == std::string::npos)) usage("--center: expected X,Y,Z");
        o.center[k] = parse_number(flag, value.substr(start, comma == std::string::npos ? std::string::npos : comma - start));
        start = comma + 1;
      }
    } else if (flag == "--radius") {
      o.radius = parse_number(flag, value);
    } else if (flag == "--period") {
      o.period = parse_number(flag, value);
      if (o.period <= 0) usage("--period must be > 0");
    } else if (flag == "--rate") {
      o.rate = parse_number(flag, value);
      if (o.rate < 1 || o.rate > 10000) usage("--rate must be in [1, 10000]");
    } else if (flag == "--duration") {
      o.duration = parse_number(flag, value);
      if (o.duration < 0) usage("--duration must be >= 0");
    } else if (flag == "--session") {
      o.session = static_cast<std::uint32_t>(parse_number(flag, value));
    } else if (flag == "--buttons") {
      o.buttons = static_cast<std::uint32_t>(parse_number(flag, value));
    } else if (flag == "--print-every") {
      o.print_every = static_cast<long>(parse_number(flag, value));
    } else {
      usage("unknown option " + flag);
    }
  }
  return o;
}

// REAL DEVICE: read the device here. With OpenHaptics this is hdGetDoublev(HD_CURRENT_TRANSFORM,
// m) (and HD_CURRENT_BUTTONS) inside an hdScheduleSynchronous callback; with CHAI3D,
// device->getPosition(p), getRotation(R) and getUserSwitch(0, b). Convert to metres and to the
// scene's axes, and the rotation to a unit quaternion (w, x, y, z), before returning.
DevicePose read_device_pose(const Options& o, double t) {
  DevicePose pose;
  pose.position = o.center;
  pose.buttons = o.buttons;
  const double phase = 2 * std::numbers::pi * t / o.period;
  if (o.script == "circle") {
    pose.position[0] += o.radius * std::cos(phase);
    pose.position[1] += o.radius * std::sin(phase);
    // Tool axis turning with the circle: rotation by `phase` about z.
    pose.orientation = {std::cos(phase / 2), 0, 0, std::sin(phase / 2)};
  } else if (o.script == "poke") {
    const double depth = o.radius * 0.5 * (1 - std::cos(phase));  // 0 -> radius -> 0
    pose.position[2] -= depth;
    if (depth > 0.05 * o.radius) pose.buttons |= 1u;
  }
  return pose;
}

// REAL DEVICE: command the force here: OpenHaptics hdSetDoublev(HD_CURRENT_FORCE, f) in the
// servo callback, CHAI3D device->setForce(f); convert from the scene's axes and newtons. Apply
// zero when the packet's state is lost (the simulator already sends zero then) and when no
// force packet has arrived for a while (the simulator is gone): never hold the last force.
void apply_force(const protocol::ForcePacket&) {}

struct Stats {
  long sent = 0, send_errors = 0, received = 0, bad = 0, lost_packets = 0;
  double max_force = 0;
  std::vector<double> round_trip_us;
};

}  // namespace

int main(int argc, char** argv) {
  const Options o = parse(argc, argv);
  std::uint32_t session = o.session;
  if (session == 0)  // a new session per run: the device then takes over from a previous run
    session = static_cast<std::uint32_t>(incise::haptics::monotonic_now_ns() ^ (std::int64_t{getpid()} << 20)) | 1u;

  const int fd = socket(AF_INET, SOCK_DGRAM | SOCK_NONBLOCK | SOCK_CLOEXEC, 0);
  sockaddr_in device{};
  device.sin_family = AF_INET;
  device.sin_port = htons(static_cast<std::uint16_t>(o.port));
  if (fd < 0 || inet_pton(AF_INET, o.host.c_str(), &device.sin_addr) != 1) {
    std::fprintf(stderr, "incise-bridge: cannot use %s:%d: %s\n", o.host.c_str(), o.port, std::strerror(errno));
    return 1;
  }
  // connect() fixes the peer: send() goes to the device, recv() only takes its packets.
  if (connect(fd, reinterpret_cast<const sockaddr*>(&device), sizeof device) != 0) {
    std::fprintf(stderr, "incise-bridge: connect %s:%d: %s\n", o.host.c_str(), o.port, std::strerror(errno));
    return 1;
  }
  if (!o.quiet)
    std::printf("bridge: %s script, session %u, %.0f Hz for %.3f s to %s:%d\n", o.script.c_str(), session, o.rate,
                o.duration, o.host.c_str(), o.port);

  Stats stats;
  constexpr std::size_t kSendHistory = 4096;  // send time by sequence, for the round trip
  std::vector<std::int64_t> send_time(kSendHistory, 0);
  const std::int64_t period_ns = static_cast<std::int64_t>(std::llround(1e9 / o.rate));
  const std::int64_t start = incise::haptics::monotonic_now_ns();
  const std::int64_t end = start + static_cast<std::int64_t>(o.duration * 1e9);
  std::int64_t deadline = start;
  std::uint64_t sequence = 0;

  for (;;) {
    const std::int64_t now = incise::haptics::monotonic_now_ns();
    if (now >= end) break;

    // 1. Read the device and send its pose.
    protocol::PosePacket pose;
    pose.session = session;
    pose.sequence = ++sequence;
    pose.timestamp_ns = now;
    pose.pose = read_device_pose(o, 1e-9 * static_cast<double>(now - start));
    const auto bytes = protocol::encode(pose);
    if (send(fd, bytes.data(), bytes.size(), MSG_DONTWAIT | MSG_NOSIGNAL) == static_cast<ssize_t>(bytes.size())) {
      ++stats.sent;
      send_time[pose.sequence % kSendHistory] = now;
    } else {
      ++stats.send_errors;  // ECONNREFUSED until the simulator listens: keep going
    }

    // 2. Take every force packet that has arrived (never wait for one) and apply the newest.
    std::uint8_t buffer[protocol::kForceSize + 1];
    protocol::ForcePacket newest;
    bool have_force = false;
    for (;;) {
      const ssize_t n = recv(fd, buffer, sizeof buffer, MSG_DONTWAIT | MSG_TRUNC);
      if (n < 0) break;
      protocol::ForcePacket force;
      if (protocol::decode_force(buffer, static_cast<std::size_t>(n), force) != protocol::Verdict::accepted) {
        ++stats.bad;
        continue;
      }
      ++stats.received;
      if (force.state == incise::haptics::DeviceState::lost) ++stats.lost_packets;
      const double magnitude = std::sqrt(force.force[0] * force.force[0] + force.force[1] * force.force[1] +
                                         force.force[2] * force.force[2]);
      if (magnitude > stats.max_force) stats.max_force = magnitude;
      if (force.pose_sequence > 0 && force.pose_sequence + kSendHistory > sequence &&
          stats.round_trip_us.size() < 1'000'000)
        stats.round_trip_us.push_back(1e-3 * static_cast<double>(incise::haptics::monotonic_now_ns() -
                                                                  send_time[force.pose_sequence % kSendHistory]));
      if (!o.quiet && o.print_every > 0 && stats.received % o.print_every == 1)
        std::printf("force t=%.3f s seq=%llu pose_seq=%llu state=%s f=(%.4f, %.4f, %.4f) N\n",
                    1e-9 * static_cast<double>(now - start), static_cast<unsigned long long>(force.sequence),
                    static_cast<unsigned long long>(force.pose_sequence), incise::haptics::to_string(force.state),
                    force.force[0], force.force[1], force.force[2]);
      newest = force;
      have_force = true;
    }
    if (have_force) apply_force(newest);

    // 3. Sleep to the next absolute deadline.
    deadline += period_ns;
    timespec target{static_cast<time_t>(deadline / 1'000'000'000), static_cast<long>(deadline % 1'000'000'000)};
    while (clock_nanosleep(CLOCK_MONOTONIC, TIMER_ABSTIME, &target, nullptr) == EINTR) {
    }
  }
  close(fd);

  const double p50 = incise::common::percentile(stats.round_trip_us, 0.5);
  const double p99 = incise::common::percentile(stats.round_trip_us, 0.99);
  std::printf("bridge: sent %ld poses (%ld send errors), received %ld forces (%ld with state lost, %ld bad), "
              "max |f| %.4f N, round trip p50 %.0f us p99 %.0f us\n",
              stats.sent, stats.send_errors, stats.received, stats.lost_packets, stats.bad, stats.max_force, p50, p99);
  return 0;
}
