// Executors for tests of results that must not depend on how a loop is split (physics/core/
// executor.hpp): the bits on these must be the serial executor's.
#pragma once

#include "physics/core/executor.hpp"

#include <algorithm>
#include <functional>
#include <thread>

namespace incise::test {

// Hands a parallel_for's ranges out in pieces of `piece`, last first, on one thread (what a pool
// of threads may do, so that a result that depended on the split would show); run_beside runs
// side() before own().
class ShufflingExecutor final : public physics::Executor {
 public:
  explicit ShufflingExecutor(int piece = 7) : piece_(piece) {}
  int thread_count() const override { return 3; }
  void parallel_for(int count, const std::function<void(int, int)>& task, int) override {
    for (int begin = (count - 1) / piece_ * piece_; begin >= 0; begin -= piece_) task(begin, std::min(count, begin + piece_));
  }
  void run_beside(const std::function<void()>& own, const std::function<void()>& side) override {
    side();
    own();
  }

 private:
  int piece_;
};

// Two threads: a parallel_for's second half on a thread of its own, the first on the caller's;
// run_beside's side() on the other thread.
class TwoThreadExecutor final : public physics::Executor {
 public:
  int thread_count() const override { return 2; }
  void parallel_for(int count, const std::function<void(int, int)>& task, int) override {
    const int half = count / 2;
    std::thread other([&] { task(half, count); });
    task(0, half);
    other.join();
  }
  void run_beside(const std::function<void()>& own, const std::function<void()>& side) override {
    std::thread other(side);
    own();
    other.join();
  }
};

}  // namespace incise::test
