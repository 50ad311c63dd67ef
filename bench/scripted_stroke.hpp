// The hand of `incise bench haptics`: the device's pose as a function of time, read by the
// loop's PathDevice (haptics/path_device.hpp) when it ticks.
#pragma once

#include "haptics/device.hpp"

namespace incise::bench {

// Strokes of 2 s, each a centimetre aside of the last (five lanes, then again): from 1 cm above
// the block's top (z = 0.03) at x = -0.03, press 10 mm in over 0.3 s, draw to x = +0.03 over
// 1.2 s (5 cm/s), lift over 0.3 s, move back over 0.2 s. Engaged (when `engage`) while it
// presses and draws. t: seconds since the run's start, >= 0.
haptics::DevicePose scripted_stroke(double t, bool engage);

}  // namespace incise::bench
