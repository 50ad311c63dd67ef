#include "haptics/replay_device.hpp"

#include <algorithm>

namespace incise::haptics {

ReplayDevice::ReplayDevice(std::vector<TimedPose> samples, const DeviceLimits& limits, Clock clock)
    : samples_(std::move(samples)), limits_(limits), clock_(std::move(clock)) {
  validate_limits(limits_, "replay device limits");
  if (samples_.empty()) throw std::invalid_argument("replay device: no samples");
  for (std::size_t i = 0; i < samples_.size(); ++i) {
    const std::string at = "replay device samples[" + std::to_string(i) + "]";
    require_finite(samples_[i].time_s, at + ".time_s");
    require_finite_pose(samples_[i].pose, at + ".pose");
    if (i > 0 && !(samples_[i].time_s > samples_[i - 1].time_s))
      throw std::invalid_argument(at + ".time_s " + std::to_string(samples_[i].time_s) +
                                  " is not after the previous sample's " + std::to_string(samples_[i - 1].time_s));
  }
}

namespace {
DevicePose interpolate(const TimedPose& a, const TimedPose& b, double t) {
  const double u = (t - a.time_s) / (b.time_s - a.time_s);
  DevicePose out;
  for (int i = 0; i < 3; ++i) out.position[i] = a.pose.position[i] + u * (b.pose.position[i] - a.pose.position[i]);
  // q and -q are the same rotation: interpolate towards the one on a's hemisphere.
  const Quaternion& qa = a.pose.orientation;
  Quaternion qb = b.pose.orientation;
  if (qa[0] * qb[0] + qa[1] * qb[1] + qa[2] * qb[2] + qa[3] * qb[3] < 0)
    for (double& c : qb) c = -c;
  for (int i = 0; i < 4; ++i) out.orientation[i] = qa[i] + u * (qb[i] - qa[i]);
  const double n = quaternion_norm(out.orientation);
  for (double& c : out.orientation) c /= n;
  out.buttons = a.pose.buttons;
  return out;
}
}  // namespace

DevicePose ReplayDevice::pose_at(double t) const {
  if (t <= samples_.front().time_s) return samples_.front().pose;
  if (t >= samples_.back().time_s) return samples_.back().pose;
  const auto after = std::upper_bound(samples_.begin(), samples_.end(), t,
                                      [](double time, const TimedPose& s) { return time < s.time_s; });
  return interpolate(*(after - 1), *after, t);
}

void ReplayDevice::open() {
  open_time_ns_ = clock_();
  cursor_ = 0;
  finished_.store(samples_.size() == 1, std::memory_order_release);
  open_ = true;
}

void ReplayDevice::close() { open_ = false; }

DevicePose ReplayDevice::read_pose() {
  const double t = samples_.front().time_s + 1e-9 * static_cast<double>(clock_() - open_time_ns_);
  // Playback moves forward: walk the cursor instead of a binary search per tick.
  while (cursor_ + 1 < samples_.size() && samples_[cursor_ + 1].time_s <= t) ++cursor_;
  if (cursor_ + 1 >= samples_.size()) {
    finished_.store(true, std::memory_order_release);
    return samples_.back().pose;
  }
  if (t <= samples_[cursor_].time_s) return samples_[cursor_].pose;
  return interpolate(samples_[cursor_], samples_[cursor_ + 1], t);
}

}  // namespace incise::haptics
