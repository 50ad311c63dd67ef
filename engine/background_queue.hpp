// One long-lived thread that runs posted jobs in order (the rest factors built beside the
// steps, Executor::run_async). A thread per job (std::async) gave each build a thread of its
// own, and glibc a malloc arena of its own now and then: the freed factors' memory stayed in
// those arenas, out of malloc_trim's reach, and a long session's RSS grew with the cuts (the
// soak, +11 % in two minutes, flat with MALLOC_ARENA_MAX=1). One thread keeps one arena,
// reused build after build; ThreadPoolExecutor keeps one for the process. Started at the first
// post, so a process that never builds a factor has no such thread.
//
// The thread runs at a lower priority (background_nice nice levels below them, on Linux) than the steps: on two
// cores a build at theirs took a core from the step's two threads for the ~15 ms it needs at
// 20k elements, two steps of the ~12 its factor waits for (RestPreconditioner's latency) paying
// for it all. Below them it takes what the steps leave idle (their serial parts, the worker
// parked) and, against a busy step, about a tenth of a core: the same work spread over the
// latency's steps. Which factor a step uses depends on the step count alone, so a build made
// slower changes no bit, at worst a wait (PreconditionerReport::wait_ms).
#pragma once

#include <condition_variable>
#include <deque>
#include <functional>
#include <future>
#include <mutex>
#include <thread>

namespace incise::engine {

class BackgroundQueue {
 public:
  static constexpr int background_nice = 10;
  BackgroundQueue() = default;
  // Runs every job posted before returning: a copy of a world may still wait on a future its
  // original's queue holds (a std::async's shared state ran its job whatever happened).
  ~BackgroundQueue();
  BackgroundQueue(const BackgroundQueue&) = delete;
  BackgroundQueue& operator=(const BackgroundQueue&) = delete;

  // Queues job() and returns its completion, which rethrows what it threw.
  std::shared_future<void> post(std::function<void()> job);

 private:
  void work();

  std::mutex mutex_;
  std::condition_variable wake_;
  std::deque<std::packaged_task<void()>> jobs_;
  bool stopping_ = false;
  std::thread thread_;  // started by the first post
};

}  // namespace incise::engine
