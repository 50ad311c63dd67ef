// The engine's threads for physics: a fixed set of worker threads that split a loop into
// contiguous ranges (WorkerPool), a helper thread that runs one job beside the caller's
// (SideRunner), and the physics::Executor built on them that the World hands its models
// (physics owns no thread). std::thread only: no OpenMP or TBB dependency.
#pragma once

#include "engine/background_queue.hpp"
#include "physics/core/executor.hpp"

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
  // thread_count >= 1; the calling thread is one of them, so thread_count - 1 are started.
  explicit WorkerPool(int thread_count);
  ~WorkerPool();
  WorkerPool(const WorkerPool&) = delete;
  WorkerPool& operator=(const WorkerPool&) = delete;

  int thread_count() const { return static_cast<int>(threads_.size()) + 1; }

  // Calls task(begin, end) on consecutive ranges that cover [0, count), one per thread used,
  // the calling thread taking the first, and returns when all are done. At most
  // count / minimum_per_thread threads are used (at least one): waking a thread costs more
  // than a small loop, and far more when the cores are busy with other work. An exception
  // thrown by a task is rethrown here. Not reentrant: one run at a time.
  void run(int count, const std::function<void(int begin, int end)>& task,
           int minimum_per_thread = 1);

 private:
  void work(int index);
  std::pair<int, int> range(int index, int count, int threads) const;

  std::vector<std::thread> threads_;
  std::mutex mutex_;
  std::condition_variable start_;
  std::condition_variable finished_;
  const std::function<void(int, int)>* task_ = nullptr;
  int count_ = 0;
  int used_ = 0;  // threads taking part in the current run
  uint64_t generation_ = 0;
  int pending_ = 0;
  bool stopping_ = false;
  std::exception_ptr error_;
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
