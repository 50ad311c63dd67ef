// The physics threads' helpers: SideRunner runs a job beside the caller's, on its helper thread
// or, when the helper has not begun it, on the caller after its own. Run under
// ThreadSanitizer in CI (what each job wrote must be seen after run returns).
#include "physics/efg/worker_pool.hpp"

#include <gtest/gtest.h>

#include <atomic>
#include <chrono>
#include <stdexcept>
#include <thread>
#include <vector>

using incise::physics::SideRunner;
using incise::physics::WorkerPool;

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
