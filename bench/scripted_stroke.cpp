#include "bench/scripted_stroke.hpp"

#include <cmath>

namespace incise::bench {

haptics::DevicePose scripted_stroke(double t, bool engage) {
  const double period = 2.0;
  const int lane = static_cast<int>(std::floor(t / period)) % 5;
  const double s = std::fmod(t, period);
  const double top = 0.03, above = top + 0.01, depth = top - 0.01;
  const double y = -0.02 + 0.01 * lane;
  haptics::DevicePose pose;
  double x = -0.03, z = above;
  bool down = false;
  if (s < 0.3) {
    z = above + (depth - above) * s / 0.3;
    down = true;
  } else if (s < 1.5) {
    x = -0.03 + 0.06 * (s - 0.3) / 1.2;
    z = depth;
    down = true;
  } else if (s < 1.8) {
    x = 0.03;
    z = depth + (above - depth) * (s - 1.5) / 0.3;
  } else {
    x = 0.03 - 0.06 * (s - 1.8) / 0.2;
  }
  pose.position = {x, y, z};
  pose.buttons = engage && down ? haptics::kButtonEngage : 0;
  return pose;
}

}  // namespace incise::bench
