// A fixed histogram of loop periods (1 us bins up to 20 ms, one overflow bin, the exact
// maximum): recording is two relaxed atomic adds, so the haptic thread records every period
// without allocating, and any thread (the window's live plot, the bench) can read percentiles
// at any time.
#pragma once

#include <array>
#include <atomic>
#include <cstdint>
#include <memory>
#include <vector>

namespace incise::haptics {

// A period over 2 ms and where it went: the wait for its deadline returned late_ns after the
// deadline (the host did not run the thread: preemption, a stall of the machine), or the tick
// before it took work_ns (a fault, a lock, an allocation in the tick itself).
struct LongPeriod {
  std::int64_t end_ns = 0;     // CLOCK_MONOTONIC, the start of the tick that ended it
  std::int64_t period_ns = 0;
  std::int64_t late_ns = 0;    // that tick's start after its deadline
  std::int64_t work_ns = 0;    // the tick before: its start to the end of its work
};

struct PeriodStatistics {
  std::uint64_t periods = 0;
  double mean_us = 0, p50_us = 0, p99_us = 0, p999_us = 0, max_us = 0;  // percentiles: 1 us resolution
  std::uint64_t over_2ms = 0;          // periods longer than 2 ms
  std::uint64_t missed_deadlines = 0;  // deadlines skipped because a tick started a period late
};

class PeriodHistogram {
 public:
  static constexpr int kBins = 20'000;  // bin i: [i, i+1) us; bin kBins: >= 20 ms
  PeriodHistogram() : bins_(std::make_unique<std::atomic<std::uint32_t>[]>(kBins + 1)) { reset(); }

  void record(std::int64_t period_ns);
  // A period over 2 ms, kept with its split; the first kLongKept are kept (no allocation).
  static constexpr int kLongKept = 512;
  void record_long(const LongPeriod& period);
  std::vector<LongPeriod> long_periods() const;  // any thread; allocates (not the haptic one)
  void record_missed(std::uint64_t n) { missed_.fetch_add(n, std::memory_order_relaxed); }
  PeriodStatistics summary() const;
  void reset();  // not concurrently with record()

 private:
  std::unique_ptr<std::atomic<std::uint32_t>[]> bins_;
  std::atomic<std::uint64_t> count_{0}, sum_ns_{0}, over_2ms_{0}, missed_{0};
  std::atomic<std::int64_t> max_ns_{0};
  std::array<LongPeriod, kLongKept> long_{};
  std::atomic<int> long_count_{0};  // entries below it are complete (written before its release)
};

// The long periods of `loop` that overlap none of `beside`'s (a bare loop run at the same
// time): those the host's stalls do not explain.
std::size_t long_periods_not_in(const std::vector<LongPeriod>& loop, const std::vector<LongPeriod>& beside);

}  // namespace incise::haptics
