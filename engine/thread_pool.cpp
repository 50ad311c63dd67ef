#include "engine/thread_pool.hpp"

#include <algorithm>
#include <stdexcept>
#include <string>

namespace incise::engine {

WorkerPool::WorkerPool(int thread_count) {
  if (thread_count < 1) {
    throw std::invalid_argument("WorkerPool: thread_count must be at least 1, got " +
                                std::to_string(thread_count));
  }
  threads_.reserve(static_cast<size_t>(thread_count - 1));
  for (int index = 1; index < thread_count; ++index) {
    threads_.emplace_back([this, index] { work(index); });
  }
}

WorkerPool::~WorkerPool() {
  {
    std::lock_guard lock(mutex_);
    stopping_ = true;
  }
  start_.notify_all();
  for (std::thread& thread : threads_) thread.join();
}

std::pair<int, int> WorkerPool::range(int index, int count, int threads) const {
  return {static_cast<int>(static_cast<long long>(count) * index / threads),
          static_cast<int>(static_cast<long long>(count) * (index + 1) / threads)};
}

void WorkerPool::run(int count, const std::function<void(int, int)>& task, int minimum_per_thread) {
  const int useful = std::max(1, count / std::max(1, minimum_per_thread));
  const int used = std::min(thread_count(), useful);
  if (used == 1) {
    task(0, count);
    return;
  }
  {
    std::lock_guard lock(mutex_);
    task_ = &task;
    count_ = count;
    used_ = used;
    pending_ = used - 1;
    error_ = nullptr;
    ++generation_;
  }
  start_.notify_all();
  std::exception_ptr own_error;
  try {
    const auto [begin, end] = range(0, count, used);
    task(begin, end);
  } catch (...) {
    own_error = std::current_exception();
  }
  std::unique_lock lock(mutex_);
  finished_.wait(lock, [this] { return pending_ == 0; });
  task_ = nullptr;
  if (own_error) std::rethrow_exception(own_error);
  if (error_) std::rethrow_exception(error_);
}

void WorkerPool::work(int index) {
  uint64_t seen = 0;
  for (;;) {
    const std::function<void(int, int)>* task = nullptr;
    int count = 0, used = 0;
    {
      std::unique_lock lock(mutex_);
      start_.wait(lock, [&] { return stopping_ || generation_ != seen; });
      if (stopping_) return;
      seen = generation_;
      task = task_;
      count = count_;
      used = used_;
    }
    if (index >= used) continue;  // not needed in this run
    std::exception_ptr error;
    try {
      const auto [begin, end] = range(index, count, used);
      (*task)(begin, end);
    } catch (...) {
      error = std::current_exception();
    }
    {
      std::lock_guard lock(mutex_);
      if (error && !error_) error_ = error;
      --pending_;
    }
    finished_.notify_one();
  }
}

SideRunner::SideRunner() : thread_([this] { work(); }) {}

SideRunner::~SideRunner() {
  {
    std::lock_guard lock(mutex_);
    stopping_ = true;
  }
  wake_.notify_all();
  thread_.join();
}

std::uint64_t SideRunner::taken_by_helper() const {
  std::lock_guard lock(mutex_);
  return taken_;
}

void SideRunner::run(const std::function<void()>& own, const std::function<void()>& side) {
  {
    std::lock_guard lock(mutex_);
    job_ = &side;
    error_ = nullptr;
  }
  wake_.notify_one();
  const std::exception_ptr own_error = physics::call_catching(own);
  bool mine = false;
  std::exception_ptr side_error;
  {
    std::unique_lock lock(mutex_);
    if (job_) {
      job_ = nullptr;  // the helper has not begun it: it is done here
      mine = true;
    } else {
      done_.wait(lock, [this] { return !running_; });
      side_error = error_;
    }
  }
  if (mine) side_error = physics::call_catching(side);
  if (own_error) std::rethrow_exception(own_error);
  if (side_error) std::rethrow_exception(side_error);
}

void SideRunner::work() {
  for (;;) {
    const std::function<void()>* job = nullptr;
    {
      std::unique_lock lock(mutex_);
      wake_.wait(lock, [this] { return stopping_ || job_ != nullptr; });
      if (stopping_) return;
      job = job_;
      job_ = nullptr;
      running_ = true;
      ++taken_;
    }
    const std::exception_ptr error = physics::call_catching(*job);
    {
      std::lock_guard lock(mutex_);
      error_ = error;
      running_ = false;
    }
    done_.notify_all();
  }
}

ThreadPoolExecutor::ThreadPoolExecutor(int thread_count, bool side_helper)
    : pool_(thread_count), side_(side_helper ? std::make_unique<SideRunner>() : nullptr) {}

void ThreadPoolExecutor::parallel_for(int count, const std::function<void(int, int)>& task,
                                      int minimum_per_thread) {
  pool_.run(count, task, minimum_per_thread);
}

void ThreadPoolExecutor::run_beside(const std::function<void()>& own,
                                    const std::function<void()>& side) {
  if (side_) {
    side_->run(own, side);
  } else {
    physics::serial_executor().run_beside(own, side);
  }
}

std::shared_future<void> ThreadPoolExecutor::run_async(std::function<void()> job) {
  // One thread for the whole process, never destroyed (its jobs own what they read): a thread
  // per body, started and ended with it, let a long session's RSS grow with every rebuilt body
  // (each new thread's first factor left memory behind: malloc arenas, BLAS buffers).
  static BackgroundQueue* const queue = new BackgroundQueue;
  return queue->post(std::move(job));
}

std::uint64_t ThreadPoolExecutor::side_taken_by_helper() const {
  return side_ ? side_->taken_by_helper() : 0;
}

}  // namespace incise::engine
