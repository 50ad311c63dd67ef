// The engine's threads for physics (engine/thread_pool.hpp): SideRunner runs a job beside the
// caller's, on its helper thread or, when the helper has not begun it, on the caller after its
// own; WorkerPool splits a loop; ThreadPoolExecutor is the physics::Executor made of them, and
// physics::serial_executor the one models use without it. Run under ThreadSanitizer in CI
// (what each job wrote must be seen after run returns). BackgroundQueue: the factors' builds' thread, in
// order, below the posting thread's priority.
#include "engine/background_queue.hpp"
#include "engine/thread_pool.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <mutex>
#include <stdexcept>
#include <string>
#include <thread>
#include <utility>
#include <vector>

#if defined(__linux__)
#include <sys/resource.h>
#include <unistd.h>
#endif

using incise::engine::BackgroundQueue;
using incise::engine::SideRunner;
using incise::engine::ThreadPoolExecutor;
using incise::engine::WorkerPool;
using incise::physics::Executor;

TEST(SideRunner, RunsBothJobsOnceAndTheirWritesAreSeenAfterwards) {
  SideRunner runner;
  const auto caller = std::this_thread::get_id();
  std::vector<int> own_values, side_values;  // plain (not atomic): run's return publishes them
  int on_caller = 0;
  const int runs = 2000;
  for (int k = 0; k < runs; ++k) {
    std::thread::id side_thread;
    runner.run([&] { own_values.push_back(k); },
               [&] {
                 side_values.push_back(2 * k);
                 side_thread = std::this_thread::get_id();
               });
    on_caller += side_thread == caller ? 1 : 0;
  }
  ASSERT_EQ(own_values.size(), static_cast<std::size_t>(runs));
  ASSERT_EQ(side_values.size(), static_cast<std::size_t>(runs));
  for (int k = 0; k < runs; ++k) {
    EXPECT_EQ(own_values[static_cast<std::size_t>(k)], k);
    EXPECT_EQ(side_values[static_cast<std::size_t>(k)], 2 * k);
  }
  // Each side job ran on the helper (counted) or on the caller, never both, never neither.
  EXPECT_EQ(static_cast<std::uint64_t>(runs - on_caller), runner.taken_by_helper());
}

TEST(SideRunner, TheHelperTakesTheSideJobWhileTheCallerIsBusy) {
  // own() waits until side() has begun: only the helper can begin it then.
  SideRunner runner;
  std::atomic<bool> side_began{false};
  std::thread::id side_thread;
  bool saw_it = false;
  runner.run(
      [&] {
        const auto give_up = std::chrono::steady_clock::now() + std::chrono::seconds(30);
        while (!side_began.load() && std::chrono::steady_clock::now() < give_up) std::this_thread::yield();
        saw_it = side_began.load();
      },
      [&] {
        side_thread = std::this_thread::get_id();
        side_began.store(true);
      });
  EXPECT_TRUE(saw_it);
  EXPECT_NE(side_thread, std::this_thread::get_id());
  EXPECT_EQ(runner.taken_by_helper(), 1u);
}

TEST(SideRunner, AnExceptionOfEitherJobIsRethrownAndTheRunnerGoesOn) {
  SideRunner runner;
  bool own_ran = false;
  EXPECT_THROW(runner.run([&] { own_ran = true; }, [] { throw std::runtime_error("side"); }), std::runtime_error);
  EXPECT_TRUE(own_ran);
  bool side_ran = false;
  try {
    runner.run([] { throw std::logic_error("own"); }, [&] { side_ran = true; });
    ADD_FAILURE() << "own's exception was not rethrown";
  } catch (const std::logic_error& error) {
    EXPECT_STREQ(error.what(), "own");
  }
  EXPECT_TRUE(side_ran);  // the side job still ran (and finished) before run returned
  int sum = 0;
  runner.run([&] { sum += 1; }, [&] { sum += 0; });
  EXPECT_EQ(sum, 1);
}

TEST(WorkerPool, CoversTheRangeOnceWhateverTheThreadCount) {
  for (const int threads : {1, 2, 3}) {
    WorkerPool pool(threads);
    std::vector<int> hits(1000, 0);
    pool.run(1000, [&](int begin, int end) {
      for (int i = begin; i < end; ++i) ++hits[static_cast<std::size_t>(i)];
    });
    for (int i = 0; i < 1000; ++i) ASSERT_EQ(hits[static_cast<std::size_t>(i)], 1) << threads << " threads, item " << i;
  }
}

// Back-to-back runs, with workers that park at once (spin 0) and with ones that poll first:
// each run's ranges are the fixed split count * i / n, n = min(count, 4 x threads), whichever
// thread took them, each item is done once, and what a range wrote is seen when run returns.
TEST(WorkerPool, BackToBackRunsGiveTheFixedRangesAndTheirWrites) {
  for (const auto spin : {std::chrono::nanoseconds(0), WorkerPool::default_spin}) {
    for (const int threads : {2, 3, 4}) {
      WorkerPool pool(threads, spin);
      std::vector<int> values(997, 0);
      for (int run = 1; run <= 300; ++run) {
        const int count = 1 + (run * 37) % static_cast<int>(values.size());
        std::mutex mutex;
        std::vector<std::pair<int, int>> ranges;
        pool.run(count, [&](int begin, int end) {
          for (int i = begin; i < end; ++i) values[static_cast<std::size_t>(i)] += run;
          std::lock_guard lock(mutex);
          ranges.emplace_back(begin, end);
        });
        std::sort(ranges.begin(), ranges.end());
        const int n = std::min(count, WorkerPool::ranges_per_thread * threads);
        ASSERT_EQ(pool.ranges(count, 1), n);
        std::vector<std::pair<int, int>> expected;
        for (int i = 0; i < n; ++i) expected.emplace_back(count * i / n, count * (i + 1) / n);
        ASSERT_EQ(ranges, expected) << threads << " threads, run " << run;
        int sum = 0;
        for (int i = 0; i < count; ++i) sum += values[static_cast<std::size_t>(i)];
        for (int i = 0; i < count; ++i) values[static_cast<std::size_t>(i)] = 0;
        ASSERT_EQ(sum, run * count) << threads << " threads, run " << run;
      }
    }
  }
}

TEST(WorkerPool, UsesAtMostOneThreadPerMinimumAndRethrowsATasksException) {
  WorkerPool pool(3);
  std::atomic<int> ranges{0};
  pool.run(10, [&](int, int) { ++ranges; }, 5);
  EXPECT_EQ(ranges.load(), 2);
  ranges = 0;
  pool.run(4, [&](int, int) { ++ranges; }, 8);
  EXPECT_EQ(ranges.load(), 1);  // on the calling thread alone
  EXPECT_THROW(pool.run(300, [](int begin, int) {
    if (begin > 0) throw std::runtime_error("worker");
  }), std::runtime_error);
  int sum = 0;
  pool.run(1, [&](int begin, int end) { sum += end - begin; });
  EXPECT_EQ(sum, 1);  // the pool goes on
}

// What the physics models may count on, whichever executor runs them.
void check_executor(Executor& executor) {
  std::vector<int> hits(777, 0);
  std::atomic<int> ranges{0};
  executor.parallel_for(777, [&](int begin, int end) {
    ++ranges;
    for (int i = begin; i < end; ++i) ++hits[static_cast<std::size_t>(i)];
  });
  for (int i = 0; i < 777; ++i) ASSERT_EQ(hits[static_cast<std::size_t>(i)], 1) << "item " << i;
  EXPECT_GE(ranges.load(), 1);
  EXPECT_LE(ranges.load(), WorkerPool::ranges_per_thread * executor.thread_count());
  ranges = 0;
  executor.parallel_for(6, [&](int, int) { ++ranges; }, 100);
  EXPECT_EQ(ranges.load(), 1);
  // run_beside: both jobs once, own on the calling thread, and own may run a parallel loop.
  const auto caller = std::this_thread::get_id();
  for (int k = 0; k < 200; ++k) {
    std::vector<int> own_values(100, 0), side_values(100, 0);
    std::thread::id own_thread;
    executor.run_beside(
        [&] {
          own_thread = std::this_thread::get_id();
          executor.parallel_for(100, [&](int begin, int end) {
            for (int i = begin; i < end; ++i) own_values[static_cast<std::size_t>(i)] = i;
          });
        },
        [&] {
          for (int i = 0; i < 100; ++i) side_values[static_cast<std::size_t>(i)] = 2 * i;
        });
    ASSERT_EQ(own_thread, caller);
    for (int i = 0; i < 100; ++i) {
      ASSERT_EQ(own_values[static_cast<std::size_t>(i)], i);
      ASSERT_EQ(side_values[static_cast<std::size_t>(i)], 2 * i);
    }
  }
  bool side_ran = false;
  try {
    executor.run_beside([] { throw std::logic_error("own"); }, [&] { side_ran = true; });
    ADD_FAILURE() << "own's exception was not rethrown";
  } catch (const std::logic_error& error) {
    EXPECT_STREQ(error.what(), "own");
  }
  EXPECT_TRUE(side_ran);
  EXPECT_THROW(executor.run_beside([] {}, [] { throw std::runtime_error("side"); }), std::runtime_error);
}

TEST(Executor, TheSerialOneRunsEverythingOnTheCallingThread) {
  Executor& serial = incise::physics::serial_executor();
  EXPECT_EQ(serial.thread_count(), 1);
  check_executor(serial);
  int order = 0, own_at = -1, side_at = -1;
  serial.run_beside([&] { own_at = order++; }, [&] { side_at = order++; });
  EXPECT_EQ(own_at, 0);
  EXPECT_EQ(side_at, 1);
}

TEST(Executor, TheThreadPoolOneKeepsTheContractForAnyThreadCount) {
  for (const int threads : {1, 2, 3}) {
    for (const bool helper : {false, true}) {
      SCOPED_TRACE(std::to_string(threads) + " threads, helper " + (helper ? "yes" : "no"));
      ThreadPoolExecutor executor(threads, helper);
      EXPECT_EQ(executor.thread_count(), threads);
      EXPECT_EQ(executor.has_side_helper(), helper);
      check_executor(executor);
      if (!helper) {
        EXPECT_EQ(executor.side_taken_by_helper(), 0u);
      }
    }
  }
  EXPECT_THROW(ThreadPoolExecutor(0, false), std::invalid_argument);
}

#if defined(__linux__)
// The factors' builds run below the steps' threads: the queue's thread background_nice nice
// levels above the thread that started it (capped at 19), and it runs its jobs in order.
TEST(BackgroundQueue, RunsItsJobsInOrderOnAThreadNicerThanThePostersOwn) {
  const int poster = getpriority(PRIO_PROCESS, static_cast<id_t>(gettid()));
  std::vector<int> order, nice;
  {
    BackgroundQueue queue;
    std::shared_future<void> last;
    for (int job = 0; job < 3; ++job)
      last = queue.post([&order, &nice, job] {
        order.push_back(job);
        nice.push_back(getpriority(PRIO_PROCESS, static_cast<id_t>(gettid())));
      });
    last.get();
  }
  EXPECT_EQ(order, (std::vector<int>{0, 1, 2}));
  EXPECT_EQ(nice, std::vector<int>(3, std::min(19, poster + BackgroundQueue::background_nice)));
  EXPECT_EQ(getpriority(PRIO_PROCESS, static_cast<id_t>(gettid())), poster);  // the poster's own is untouched
}
#endif
