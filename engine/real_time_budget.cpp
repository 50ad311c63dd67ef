#include "engine/real_time_budget.hpp"

#include <utility>

namespace incise::engine {

void RealTimeBudget::repeat(std::vector<CgStop> recorded) {
  recorded_ = std::move(recorded);
  next_recorded_ = 0;
}

void RealTimeBudget::begin_step(std::uint64_t step, std::int64_t cg_deadline_ns) {
  step_ = step;
  solve_ = 0;
  deadline_ns_ = cg_deadline_ns;
  while (next_recorded_ < recorded_.size() && recorded_[next_recorded_].step < step) ++next_recorded_;
}

const CgStop* RealTimeBudget::recorded_for_this_solve() const {
  for (std::size_t i = next_recorded_; i < recorded_.size() && recorded_[i].step == step_; ++i)
    if (recorded_[i].solve == solve_) return &recorded_[i];
  return nullptr;
}

physics::CgBudget RealTimeBudget::next() const {
  physics::CgBudget budget;
  budget.min_iterations = min_iterations_;
  if (const CgStop* stop = recorded_for_this_solve()) {
    budget.stop_at = static_cast<int>(stop->iterations);
  } else {
    budget.deadline_ns = deadline_ns_;
  }
  return budget;
}

void RealTimeBudget::solved(const physics::CgResult& result) {
  if (result.stopped_by_budget) {
    if (recorded_for_this_solve()) {
      ++repeated_stops_;
    } else {
      made_.push_back({step_, solve_, static_cast<std::uint32_t>(result.iterations)});
      ++deadline_stops_;
    }
  }
  ++solve_;
}

std::vector<CgStop> RealTimeBudget::take_stops() { return std::exchange(made_, {}); }

void RealTimeBudget::reset() {
  next_recorded_ = 0;
  step_ = 0;
  solve_ = 0;
  deadline_ns_ = 0;
  made_.clear();
  deadline_stops_ = repeated_stops_ = 0;
}

}  // namespace incise::engine
