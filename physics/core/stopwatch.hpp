// Wall time of a stage, for the step's report (MuJoCo keeps its timers in the data likewise:
// every run can say where its time went). Never an input to the simulation.
#pragma once

#include <chrono>

namespace incise::physics {

class Stopwatch {
 public:
  Stopwatch() : start_(std::chrono::steady_clock::now()) {}
  double ms() const { return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start_).count(); }
  void restart() { start_ = std::chrono::steady_clock::now(); }

 private:
  std::chrono::steady_clock::time_point start_;
};

}  // namespace incise::physics
