// A fixed histogram of loop periods (1 us bins up to 20 ms, one overflow bin, the exact
// maximum): recording is two relaxed atomic adds, so the haptic thread records every period
// without allocating, and any thread (the window's live plot, the bench) can read percentiles
// at any time.
#pragma once

#include <array>
#include <atomic>
#include <cstdint>
#include <memory>

namespace incise::haptics {

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
  void record_missed(std::uint64_t n) { missed_.fetch_add(n, std::memory_order_relaxed); }
  PeriodStatistics summary() const;
  void reset();  // not concurrently with record()

 private:
  std::unique_ptr<std::atomic<std::uint32_t>[]> bins_;
  std::atomic<std::uint64_t> count_{0}, sum_ns_{0}, over_2ms_{0}, missed_{0};
  std::atomic<std::int64_t> max_ns_{0};
};

}  // namespace incise::haptics
