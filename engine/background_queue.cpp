#include "engine/background_queue.hpp"

#include <algorithm>
#include <utility>

#if defined(__linux__)
#include <sys/resource.h>
#include <unistd.h>
#endif

namespace incise::engine {

BackgroundQueue::~BackgroundQueue() {
  {
    std::lock_guard lock(mutex_);
    stopping_ = true;
  }
  wake_.notify_all();
  if (thread_.joinable()) thread_.join();
}

std::shared_future<void> BackgroundQueue::post(std::function<void()> job) {
  std::packaged_task<void()> task(std::move(job));
  std::shared_future<void> done = task.get_future().share();
  {
    std::lock_guard lock(mutex_);
    jobs_.push_back(std::move(task));
    if (!thread_.joinable()) thread_ = std::thread([this] { work(); });
  }
  wake_.notify_one();
  return done;
}

void BackgroundQueue::work() {
#if defined(__linux__)
  // Linux's nice value is a thread's own: this one goes background_nice below the thread that
  // started it (the process's, which the steps' threads share). Raising one's nice value needs
  // no privilege; a refusal would leave it at theirs.
  const auto self = static_cast<id_t>(gettid());
  setpriority(PRIO_PROCESS, self, std::min(19, getpriority(PRIO_PROCESS, self) + background_nice));
#endif
  for (;;) {
    std::packaged_task<void()> task;
    {
      std::unique_lock lock(mutex_);
      wake_.wait(lock, [this] { return stopping_ || !jobs_.empty(); });
      if (jobs_.empty()) return;  // stopping, and every job posted has run
      task = std::move(jobs_.front());
      jobs_.pop_front();
    }
    task();  // its exception goes to its future
  }
}

}  // namespace incise::engine
