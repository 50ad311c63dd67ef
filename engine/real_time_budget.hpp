// Real time (issue 29): the CG budget of a world's steps. A live session gives each step a
// deadline (engine/haptic_session.hpp: when the hand will be a step further); every CG of the
// step stops there after at least `min_iterations`, and the stops it made are kept for the
// recording. A replay gives the recording's stops instead, and each of those CGs stops after
// exactly the iterations the session's did (physics/core/cg.hpp, CgBudget), so the replay
// takes the same steps on any machine.
#pragma once

#include "engine/trajectory.hpp"
#include "physics/core/cg.hpp"

#include <cstdint>
#include <vector>

namespace incise::engine {

class RealTimeBudget {
 public:
  explicit RealTimeBudget(int min_iterations = 1) : min_iterations_(min_iterations) {}

  // The stops to repeat (a recording's, in (step, solve) order).
  void repeat(std::vector<CgStop> recorded);
  // Step `step` (1 for the first) starts; its CGs stop at `cg_deadline_ns` (steady_now_ns
  // clock; 0: none). Stops recorded for the step take precedence over the deadline.
  void begin_step(std::uint64_t step, std::int64_t cg_deadline_ns);
  // The budget of the step's next CG.
  physics::CgBudget next() const;
  // That CG's result: a stop the deadline made is kept; the next CG of the step follows.
  void solved(const physics::CgResult& result);
  // The stops the deadline made since the last call, in order.
  std::vector<CgStop> take_stops();
  // The stops the deadline made, all told, and the recorded ones repeated.
  std::uint64_t deadline_stops() const { return deadline_stops_; }
  std::uint64_t repeated_stops() const { return repeated_stops_; }
  // Back to before the first step, keeping the recorded stops.
  void reset();

 private:
  const CgStop* recorded_for_this_solve() const;

  int min_iterations_;
  std::vector<CgStop> recorded_;
  std::size_t next_recorded_ = 0;  // the first recorded stop not before this step
  std::uint64_t step_ = 0;
  std::uint32_t solve_ = 0;
  std::int64_t deadline_ns_ = 0;
  std::vector<CgStop> made_;
  std::uint64_t deadline_stops_ = 0, repeated_stops_ = 0;
};

}  // namespace incise::engine
