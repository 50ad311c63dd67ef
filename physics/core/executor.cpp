#include "physics/core/executor.hpp"

#include <exception>

namespace incise::physics {

Executor::~Executor() = default;

void SerialExecutor::parallel_for(int count, const std::function<void(int, int)>& task, int) {
  task(0, count);
}

void SerialExecutor::run_beside(const std::function<void()>& own, const std::function<void()>& side) {
  // Both run even when own() throws, as they would on two threads; own's error comes first.
  std::exception_ptr own_error;
  try {
    own();
  } catch (...) {
    own_error = std::current_exception();
  }
  std::exception_ptr side_error;
  try {
    side();
  } catch (...) {
    side_error = std::current_exception();
  }
  if (own_error) std::rethrow_exception(own_error);
  if (side_error) std::rethrow_exception(side_error);
}

Executor& serial_executor() {
  static SerialExecutor executor;
  return executor;
}

}  // namespace incise::physics
