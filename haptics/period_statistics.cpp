#include "haptics/period_statistics.hpp"

#include <algorithm>

namespace incise::haptics {

void PeriodHistogram::record(std::int64_t period_ns) {
  if (period_ns < 0) period_ns = 0;
  const std::int64_t bin = std::min<std::int64_t>(period_ns / 1000, kBins);
  bins_[bin].fetch_add(1, std::memory_order_relaxed);
  sum_ns_.fetch_add(static_cast<std::uint64_t>(period_ns), std::memory_order_relaxed);
  if (period_ns > 2'000'000) over_2ms_.fetch_add(1, std::memory_order_relaxed);
  if (period_ns > max_ns_.load(std::memory_order_relaxed)) max_ns_.store(period_ns, std::memory_order_relaxed);
  count_.fetch_add(1, std::memory_order_release);
}

PeriodStatistics PeriodHistogram::summary() const {
  PeriodStatistics s;
  s.periods = count_.load(std::memory_order_acquire);
  s.over_2ms = over_2ms_.load(std::memory_order_relaxed);
  s.missed_deadlines = missed_.load(std::memory_order_relaxed);
  s.max_us = 1e-3 * static_cast<double>(max_ns_.load(std::memory_order_relaxed));
  if (s.periods == 0) return s;
  s.mean_us = 1e-3 * static_cast<double>(sum_ns_.load(std::memory_order_relaxed)) / static_cast<double>(s.periods);
  // Percentile = the bin where the cumulative count first reaches q * total (the bins' own
  // total, which a concurrent record() may have moved past `periods`).
  std::uint64_t total = 0;
  for (int i = 0; i <= kBins; ++i) total += bins_[i].load(std::memory_order_relaxed);
  const double targets[3] = {0.5, 0.99, 0.999};
  double* outputs[3] = {&s.p50_us, &s.p99_us, &s.p999_us};
  std::uint64_t cumulative = 0;
  int next = 0;
  for (int i = 0; i <= kBins && next < 3; ++i) {
    cumulative += bins_[i].load(std::memory_order_relaxed);
    while (next < 3 && static_cast<double>(cumulative) >= targets[next] * static_cast<double>(total)) {
      *outputs[next] = i == kBins ? s.max_us : static_cast<double>(i) + 0.5;
      ++next;
    }
  }
  return s;
}

void PeriodHistogram::record_long(const LongPeriod& period) {
  const int n = long_count_.load(std::memory_order_relaxed);
  if (n >= kLongKept) return;
  long_[static_cast<std::size_t>(n)] = period;
  long_count_.store(n + 1, std::memory_order_release);
}

std::vector<LongPeriod> PeriodHistogram::long_periods() const {
  const int n = long_count_.load(std::memory_order_acquire);
  return {long_.begin(), long_.begin() + n};
}

std::size_t long_periods_not_in(const std::vector<LongPeriod>& loop, const std::vector<LongPeriod>& beside) {
  std::size_t alone = 0;
  for (const LongPeriod& a : loop) {
    bool shared = false;
    for (const LongPeriod& b : beside)
      shared = shared || (a.end_ns - a.period_ns < b.end_ns && b.end_ns - b.period_ns < a.end_ns);
    alone += shared ? 0 : 1;
  }
  return alone;
}

void PeriodHistogram::reset() {
  long_count_.store(0);
  for (int i = 0; i <= kBins; ++i) bins_[i].store(0, std::memory_order_relaxed);
  count_.store(0);
  sum_ns_.store(0);
  over_2ms_.store(0);
  missed_.store(0);
  max_ns_.store(0);
}

}  // namespace incise::haptics
