#include "physics/efg/worker_pool.hpp"

#include <stdexcept>
#include <string>

namespace incise::physics {

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

std::pair<int, int> WorkerPool::range(int index, int count) const {
  const long long threads = thread_count();
  return {static_cast<int>(count * index / threads), static_cast<int>(count * (index + 1) / threads)};
}

void WorkerPool::run(int count, const std::function<void(int, int)>& task) {
  if (threads_.empty()) {
    task(0, count);
    return;
  }
  {
    std::lock_guard lock(mutex_);
    task_ = &task;
    count_ = count;
    pending_ = static_cast<int>(threads_.size());
    error_ = nullptr;
    ++generation_;
  }
  start_.notify_all();
  std::exception_ptr own_error;
  try {
    const auto [begin, end] = range(0, count);
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
    int count = 0;
    {
      std::unique_lock lock(mutex_);
      start_.wait(lock, [&] { return stopping_ || generation_ != seen; });
      if (stopping_) return;
      seen = generation_;
      task = task_;
      count = count_;
    }
    std::exception_ptr error;
    try {
      const auto [begin, end] = range(index, count);
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

}  // namespace incise::physics
