// Bounded waiting before a thread parks on a condition variable. The solver's parallel loops
// are regions of tens to hundreds of microseconds with a few microseconds of serial work between
// them, and a parked thread pays a futex wake-up at each (about 10 us on an idle two-vCPU VM,
// far more when the cores are busy). A waiting thread polls for at most `limit`, with a pause
// instruction for the first microseconds and then yielding the core between polls, and then
// parks: it never keeps a core from a thread that needs it (when the cores are oversubscribed,
// the very thread it waits for may be queued behind it), and a SCHED_FIFO haptic loop preempts
// it anyway.
#pragma once

#include <chrono>
#include <thread>

#if defined(__x86_64__) || defined(__i386__)
#include <immintrin.h>
#endif

namespace incise::engine {

// Tells the core this thread is spinning (fewer pipeline flushes, the sibling hyperthread runs).
inline void cpu_relax() {
#if defined(__x86_64__) || defined(__i386__)
  _mm_pause();
#elif defined(__aarch64__)
  asm volatile("yield");
#endif
}

// Polls ready() until it returns true (true) or `limit` has passed (false). The clock is read
// every few polls only: a read costs about as much as the pause it would replace. Past the
// first microseconds each round yields: on a free core that returns at once, on a busy one it
// lets the queued thread (perhaps the one that makes ready() true) run.
template <typename Ready>
bool spin_until(const Ready& ready, std::chrono::nanoseconds limit) {
  if (ready()) return true;
  if (limit <= std::chrono::nanoseconds::zero()) return false;
  constexpr std::chrono::nanoseconds pause_only{std::chrono::microseconds(5)};
  const auto start = std::chrono::steady_clock::now();
  const auto end = start + limit;
  for (;;) {
    for (int k = 0; k < 16; ++k) {
      cpu_relax();
      if (ready()) return true;
    }
    const auto now = std::chrono::steady_clock::now();
    if (now >= end) return ready();
    if (now - start >= pause_only) std::this_thread::yield();
  }
}

}  // namespace incise::engine
