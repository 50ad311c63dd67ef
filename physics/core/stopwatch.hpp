// Wall time of a stage, for the step's report (MuJoCo keeps its timers in the data likewise:
// every run can say where its time went). Never an input to the simulation.
#pragma once

#include <chrono>
#include <cstdint>
#include <time.h>

namespace incise::physics {

// CLOCK_MONOTONIC in nanoseconds: the haptic loop's clock (haptics/clock.hpp), so a deadline
// set from the hand's time can be checked inside a solve.
inline std::int64_t steady_now_ns() {
  timespec now{};
  clock_gettime(CLOCK_MONOTONIC, &now);
  return std::int64_t{now.tv_sec} * 1'000'000'000 + now.tv_nsec;
}

class Stopwatch {
 public:
  Stopwatch() : start_(std::chrono::steady_clock::now()) {}
  double ms() const { return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start_).count(); }
  void restart() { start_ = std::chrono::steady_clock::now(); }

 private:
  std::chrono::steady_clock::time_point start_;
};

}  // namespace incise::physics
