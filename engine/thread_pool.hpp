// The engine's threads for physics: a fixed set of worker threads that split a loop into
// contiguous ranges (WorkerPool), a helper thread that runs one job beside the caller's
// (SideRunner), and the physics::Executor built on them that the World hands its models
// (physics owns no thread). std::thread only: no OpenMP or TBB dependency.
#pragma once

#include "engine/background_queue.hpp"
#include "physics/core/executor.hpp"

#include <atomic>
#include <chrono>
#include <condition_variable>
#include <cstdint>
#include <exception>
#include <functional>
#include <memory>
#include <mutex>
#include <thread>
#include <vector>

namespace incise::engine {

class WorkerPool {
 public:
  // How long a waiting thread polls before it parks (engine/spin_wait.hpp): longer than the
  // serial gaps between a CG iteration's regions, short beside a step.
  static constexpr std::chrono::nanoseconds default_spin{std::chrono::microseconds(50)};
  // Most ranges a run is split into per thread of the pool, taken in turn by whichever thread
  // is free: a thread the system preempts (for the background factor build or another process)
  // holds up only the range it is in, not its share of the loop.
  static constexpr int ranges_per_thread = 4;

  // thread_count >= 1; the calling thread is one of them, so thread_count - 1 are started.
  // `spin`: how long a worker waits for the next run, and the caller for the workers, before
  // parking on a condition variable (0: park at once).
  explicit WorkerPool(int thread_count, std::chrono::nanoseconds spin = default_spin);
  ~WorkerPool();
  WorkerPool(const WorkerPool&) = delete;
  WorkerPool& operator=(const WorkerPool&) = delete;

  int thread_count() const { return static_cast<int>(threads_.size()) + 1; }

  // Ranges run(count, ..., minimum_per_thread) splits [0, count) into: at most count /
  // minimum_per_thread (at least one), at most ranges_per_thread per thread. Range i is
  // [count * i / n, count * (i + 1) / n): the split depends on nothing else.
  int ranges(int count, int minimum_per_thread) const;

  // Calls task(begin, end) on the ranges above and returns when all are done; the calling
  // thread takes them too, so a worker the system wakes late never makes it wait. With one
  // range it runs on the calling thread alone: waking a thread costs more than a small loop,
  // and far more when the cores are busy with other work. An exception thrown by a task is
  // rethrown here (the first caught). Not reentrant: one run at a time.
  void run(int count, const std::function<void(int begin, int end)>& task,
           int minimum_per_thread = 1);

 private:
  void work();
  // Waits until a run newer than `seen` is posted (false: the pool is stopping).
  bool wait_for_run(std::uint64_t seen);
  void wait_for_ranges();
  // Runs the current run's ranges that no thread has taken, one at a time, until none is left.
  void take_ranges();

  std::vector<std::thread> threads_;
  const std::chrono::nanoseconds spin_;
  std::mutex mutex_;                  // for parking, and error_
  std::condition_variable start_;     // a parked worker waits here for a run
  std::condition_variable finished_;  // a parked caller waits here for the last range
  // The current run: written by run() before it opens the ranges (next_, release) and read by
  // a thread that takes one (acquire), which run() waits for before it writes them again.
  const std::function<void(int, int)>* task_ = nullptr;
  int count_ = 0;
  int ranges_ = 0;
  alignas(64) std::atomic<int> next_{0};  // the next range to take minus ranges_ (>= 0: none left)
  alignas(64) std::atomic<std::uint64_t> generation_{0};  // runs posted
  alignas(64) std::atomic<int> pending_{0};  // ranges of the current run not done
  std::atomic<int> parked_workers_{0};
  std::atomic<bool> caller_parked_{false};
  std::atomic<bool> stopping_{false};
  std::exception_ptr error_;  // the run's first, under mutex_
};

// One helper thread for one job beside the caller's own: run(own, side) calls own() on the
// calling thread and side() on the helper, or on the calling thread after own() when the
// helper has not begun it by then, so that a helper the system wakes late never makes the
// caller wait for it (a pool's run must wait for every thread it wakes to check in). Returns
// when both are done; an exception of either is rethrown here (own's first). Not reentrant.
class SideRunner {
 public:
  SideRunner();
  ~SideRunner();
  SideRunner(const SideRunner&) = delete;
  SideRunner& operator=(const SideRunner&) = delete;

  void run(const std::function<void()>& own, const std::function<void()>& side);
  // Runs so far whose side job the helper took (the others ran on the calling thread).
  std::uint64_t taken_by_helper() const;

 private:
  void work();

  mutable std::mutex mutex_;
  std::condition_variable wake_;
  std::condition_variable done_;
  const std::function<void()>* job_ = nullptr;  // posted and not yet taken
  bool running_ = false;                        // the helper took the job and runs it
  bool stopping_ = false;
  std::uint64_t taken_ = 0;
  std::exception_ptr error_;  // the helper's, for the current run
  std::thread thread_;        // last: started once the rest is set up
};

// parallel_for on a WorkerPool of thread_count threads (the caller among them); run_beside on
// a SideRunner's helper when made with one, else own() then side() on the calling thread.
// The helper is a thread of its own, beside the pool's: the caller's own job may run
// parallel_for while the helper runs the side job.
class ThreadPoolExecutor final : public physics::Executor {
 public:
  ThreadPoolExecutor(int thread_count, bool side_helper);

  int thread_count() const override { return pool_.thread_count(); }
  void parallel_for(int count, const std::function<void(int begin, int end)>& task,
                    int minimum_per_thread = 1) override;
  void run_beside(const std::function<void()>& own, const std::function<void()>& side) override;
  // On the process's background thread (BackgroundQueue: one for every executor, jobs in
  // order), beside the pool's and the helper's.
  std::shared_future<void> run_async(std::function<void()> job) override;

  bool has_side_helper() const { return side_ != nullptr; }
  // Runs so far whose side job the helper took (0 without a helper).
  std::uint64_t side_taken_by_helper() const;

 private:
  WorkerPool pool_;
  std::unique_ptr<SideRunner> side_;
};

}  // namespace incise::engine
