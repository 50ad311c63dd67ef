#include "engine/thread_pool.hpp"

#include "engine/spin_wait.hpp"

#include <algorithm>
#include <stdexcept>
#include <string>

namespace incise::engine {

WorkerPool::WorkerPool(int thread_count, std::chrono::nanoseconds spin) : spin_(spin) {
  if (thread_count < 1) {
    throw std::invalid_argument("WorkerPool: thread_count must be at least 1, got " +
                                std::to_string(thread_count));
  }
  threads_.reserve(static_cast<size_t>(thread_count - 1));
  for (int index = 1; index < thread_count; ++index) threads_.emplace_back([this] { work(); });
}

WorkerPool::~WorkerPool() {
  stopping_.store(true);
  {
    std::lock_guard lock(mutex_);  // a worker about to park sees stopping_ or is woken below
  }
  start_.notify_all();
  for (std::thread& thread : threads_) thread.join();
}

int WorkerPool::ranges(int count, int minimum_per_thread) const {
  const int useful = std::max(1, count / std::max(1, minimum_per_thread));
  return std::min(useful, ranges_per_thread * thread_count());
}

void WorkerPool::run(int count, const std::function<void(int, int)>& task, int minimum_per_thread) {
  const int ranges = this->ranges(count, minimum_per_thread);
  if (ranges == 1) {
    task(0, count);
    return;
  }
  task_ = &task;
  count_ = count;
  ranges_ = ranges;
  pending_.store(ranges, std::memory_order_relaxed);
  {
    std::lock_guard lock(mutex_);
    error_ = nullptr;
  }
  next_.store(-ranges, std::memory_order_release);  // opens the ranges: publishes the run
  // Sequentially consistent with the parked count, as a worker parks (wait_for_run): either it
  // sees this run or this sees it parked and wakes it.
  generation_.fetch_add(1);
  if (parked_workers_.load() > 0) {
    std::lock_guard lock(mutex_);
    start_.notify_all();
  }
  take_ranges();
  wait_for_ranges();
  task_ = nullptr;
  std::lock_guard lock(mutex_);
  if (error_) std::rethrow_exception(error_);
}

void WorkerPool::take_ranges() {
  for (;;) {
    // A worker still in an earlier run takes from this one or finds none left: either way it
    // reads the run's fields only after taking a range of it.
    const int taken = next_.fetch_add(1, std::memory_order_acq_rel);
    if (taken >= 0) return;
    const int index = ranges_ + taken;
    try {
      (*task_)(static_cast<int>(static_cast<long long>(count_) * index / ranges_),
               static_cast<int>(static_cast<long long>(count_) * (index + 1) / ranges_));
    } catch (...) {
      std::lock_guard lock(mutex_);
      if (!error_) error_ = std::current_exception();
    }
    // The last range done wakes a parked caller; nothing of the run is touched after this, as
    // the caller may have posted the next one.
    if (pending_.fetch_sub(1) == 1 && caller_parked_.load()) {
      std::lock_guard lock(mutex_);
      finished_.notify_one();
    }
  }
}

void WorkerPool::wait_for_ranges() {
  if (spin_until([this] { return pending_.load(std::memory_order_acquire) == 0; }, spin_)) return;
  std::unique_lock lock(mutex_);
  caller_parked_.store(true);
  finished_.wait(lock, [this] { return pending_.load() == 0; });
  caller_parked_.store(false);
}

bool WorkerPool::wait_for_run(std::uint64_t seen) {
  const auto posted = [&] { return stopping_.load() || generation_.load() != seen; };
  if (!spin_until(posted, spin_)) {
    std::unique_lock lock(mutex_);
    parked_workers_.fetch_add(1);
    start_.wait(lock, posted);
    parked_workers_.fetch_sub(1);
  }
  return !stopping_.load();
}

void WorkerPool::work() {
  std::uint64_t seen = 0;
  while (wait_for_run(seen)) {
    seen = generation_.load();
    take_ranges();
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
