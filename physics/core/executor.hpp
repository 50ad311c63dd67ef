// How physics runs its parallel loops without owning a thread (physics is pure computation):
// the engine hands a model an Executor built on its threads, and a model given none runs
// every loop on the calling thread (serial_executor).
//
// Results must not depend on the executor: a caller splits its work into fixed pieces whose
// order of reduction it chooses itself (CorotationalEfg's partitions), never into the ranges
// an executor happens to hand out.
#pragma once

#include <exception>
#include <functional>
#include <future>

namespace incise::physics {

class Executor {
 public:
  virtual ~Executor();

  // Threads that may run a parallel_for's ranges at once (>= 1), the calling thread included.
  virtual int thread_count() const = 0;

  // Calls task(begin, end) on consecutive, disjoint ranges that cover [0, count), the calling
  // thread taking the first, and returns when all are done. At most count / minimum_per_thread
  // ranges (at least one): handing a small loop to another thread costs more than it saves.
  // An exception thrown by a task is rethrown here. Not reentrant: one call at a time.
  virtual void parallel_for(int count, const std::function<void(int begin, int end)>& task,
                            int minimum_per_thread = 1) = 0;

  // Calls own() on the calling thread and side() on another thread or on this one (before or
  // after own(), as the executor chooses), so the two must not touch what the other writes.
  // Returns when both are done; an exception of either is rethrown here (own's first). own()
  // may call parallel_for; side() may not. Not reentrant.
  virtual void run_beside(const std::function<void()>& own, const std::function<void()>& side) = 0;

  // Starts job() to run beside the calls that follow (a rest-shape factor built over several
  // steps) and returns its completion, which rethrows what it threw. This default runs it
  // here, before returning: an executor with threads to spare runs it on one of them. The job
  // must read and write only what it owns.
  virtual std::shared_future<void> run_async(std::function<void()> job);
};

// Every loop on the calling thread, in one range; run_beside calls own() then side(). It
// keeps no state, so any number of threads may share it.
class SerialExecutor final : public Executor {
 public:
  int thread_count() const override { return 1; }
  void parallel_for(int count, const std::function<void(int begin, int end)>& task,
                    int minimum_per_thread = 1) override;
  void run_beside(const std::function<void()>& own, const std::function<void()>& side) override;
};

// The executor of models given none.
Executor& serial_executor();

// Calls job() and returns what it threw (null when nothing): run_beside's jobs both run even
// when one throws, as they would on two threads, and their errors are rethrown afterwards.
std::exception_ptr call_catching(const std::function<void()>& job);

}  // namespace incise::physics
