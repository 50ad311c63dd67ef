// One clock for the haptic side: CLOCK_MONOTONIC in nanoseconds. Devices and the loop take a
// Clock so tests (and headless replay, which runs on simulated time) can inject their own;
// calling a std::function does not allocate, so it is fine on the 1 kHz path.
#pragma once

#include <atomic>
#include <cstdint>
#include <functional>
#include <time.h>

namespace incise::haptics {

using Clock = std::function<std::int64_t()>;  // nanoseconds, never decreasing

inline std::int64_t monotonic_now_ns() {
  timespec now{};
  clock_gettime(CLOCK_MONOTONIC, &now);
  return std::int64_t{now.tv_sec} * 1'000'000'000 + now.tv_nsec;
}

inline Clock monotonic_clock() { return &monotonic_now_ns; }

// A clock that only moves when told to (tests, simulated time). Safe to read from any thread.
class ManualClock {
 public:
  explicit ManualClock(std::int64_t start_ns = 0) : now_(start_ns) {}
  std::int64_t now_ns() const { return now_.load(std::memory_order_acquire); }
  void set_ns(std::int64_t t) { now_.store(t, std::memory_order_release); }
  void advance_ns(std::int64_t dt) { now_.fetch_add(dt, std::memory_order_acq_rel); }
  Clock clock() const { return [this] { return now_ns(); }; }

 private:
  std::atomic<std::int64_t> now_;
};

}  // namespace incise::haptics
