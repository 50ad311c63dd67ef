#include "physics/core/executor.hpp"

#include <exception>

namespace incise::physics {

Executor::~Executor() = default;

std::shared_future<void> Executor::run_async(std::function<void()> job) {
  std::promise<void> done;
  if (const std::exception_ptr error = call_catching(job))
    done.set_exception(error);
  else
    done.set_value();
  return done.get_future().share();
}

void SerialExecutor::parallel_for(int count, const std::function<void(int, int)>& task, int) {
  task(0, count);
}

void SerialExecutor::run_beside(const std::function<void()>& own, const std::function<void()>& side) {
  // Both run even when own() throws, as they would on two threads; own's error comes first.
  const std::exception_ptr own_error = call_catching(own);
  const std::exception_ptr side_error = call_catching(side);
  if (own_error) std::rethrow_exception(own_error);
  if (side_error) std::rethrow_exception(side_error);
}

std::exception_ptr call_catching(const std::function<void()>& job) {
  try {
    job();
  } catch (...) {
    return std::current_exception();
  }
  return nullptr;
}

Executor& serial_executor() {
  static SerialExecutor executor;
  return executor;
}

}  // namespace incise::physics
