// A fixed set of worker threads that split a loop into contiguous ranges (std::thread only:
// the physics library takes no OpenMP or TBB dependency).
#pragma once

#include <condition_variable>
#include <cstdint>
#include <exception>
#include <functional>
#include <mutex>
#include <thread>
#include <vector>

namespace incise::physics {

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

}  // namespace incise::physics
