// Time-domain passivity (Hannaford & Ryu 2002, "Time-domain passivity control of haptic
// interfaces", IEEE Trans. Robotics and Automation 18(1)): a passivity observer that books
// the energy the virtual environment exchanges with the device each tick, and a passivity
// controller, a variable damper that acts only while the observer says the environment has
// given the device net energy, sized to dissipate exactly that excess over the next tick.
//
// Sign convention: energy() is the net energy the virtual environment (tissue, coupling, and
// this controller's damper) has given the device, J. A passive environment starts at 0 and
// never goes above it: what the hand puts in (pressing into a spring) makes it negative, what
// the environment gives back makes it rise again, at most to 0. Hannaford & Ryu's E_obs is
// its negative (energy into the environment).
//
// The observer. The loop writes a force at each tick and the device holds it until the next
// (zero-order hold), while the device moves from x_k-1 to x_k. The work that held force did
// on the device is exactly F_k-1 . (x_k - x_k-1), with no velocity estimate: that is what the
// observer sums (Hannaford & Ryu's f v dT with v dT replaced by the displacement it
// approximates; Ryu, Kwon & Hannaford 2004 book the same one-sample-delayed product).
//
// The controller. At tick k, with E = energy() > 0 and the device's velocity v (the loop's
// filtered estimate: the next displacement is predicted as d = v T), the damper force
// -(E / |d|^2) d dissipates E if the next displacement is d (Hannaford & Ryu's alpha =
// -E_obs / (v^2 dT)). Its bounds keep it from becoming the instability it fights, or a jolt:
// the damping alpha = E T / |d|^2 is capped at max_damping (a slow hand would otherwise get an
// unbounded damper), the damper's force changes by at most max_step per tick (a damper that
// springs on in one tick is a force jump the hand feels; the raw displacement of a device
// sampled unevenly would make it chatter), and the output force stays within the device's
// max_force. What it leaves (a capped or ramping damper, a hand that changed speed) the
// observer sees at the next tick, and the controller goes on: dissipation is spread over ticks,
// never skipped. Once the excess is gone the damper lets go at the same rate (max_step a tick).
#pragma once

#include <cstdint>

#include "haptics/device.hpp"

namespace incise::haptics {

struct PassivityParameters {
  bool enabled = true;  // false: observe only (the energy is still booked)
  // N s/m, the most damping the controller adds. A damper B on a device of mass m, sampled at
  // period T with a backward-difference velocity, moves x_k+1 - x_k = (1 - B T / m)(x_k - x_k-1):
  // it is stable while B T / m < 2. 2 N s/m at 1 kHz keeps that for any device above 1 g, and
  // is several times the loop's own dampers (coupling K T = 0.3 N s/m, contact k_eff T up to
  // 0.4 N s/m at the defaults), so it can take what they miss.
  double max_damping = 2.0;
  // N, the most the damper's force changes between ticks: of the order of the force change
  // between physics publications the loop renders anyway (bench haptics, "between").
  double max_step = 0.02;
};

// Throws std::invalid_argument naming the field for a non-finite or negative max_damping or max_step.
void validate(const PassivityParameters& parameters);

struct PassivityFigures {
  double device_energy_J = 0;  // net energy the environment (damper included) gave the device
  double dissipated_J = 0;     // energy the controller's damper took from the device (>= 0 in practice)
  std::uint64_t ticks_acted = 0;  // ticks at which the controller added a damper
};

class PassivityController {
 public:
  explicit PassivityController(PassivityParameters parameters = {});

  // One tick: books the work the force written at the previous tick did while the device moved
  // to x, then returns the force to write now: `force` (what the environment renders, already
  // clamped) plus the damper when the device holds net energy (velocity: the device's, m/s),
  // clamped to max_force. render = false (a lost device): the output is zero and the damper
  // lets go. Non-finite inputs book no work. No allocation, no lock: the haptic thread calls it
  // every tick.
  Vector3 tick(const Vector3& x, const Vector3& velocity, const Vector3& force, double period_s, double max_force,
               bool render = true);

  // The part of the last output the controller added (output - force), N.
  const Vector3& damper_force() const { return damper_; }
  // The work of the last held force over the last interval, J (what tick() booked last).
  double last_work() const { return last_work_; }
  double energy() const { return figures_.device_energy_J; }
  const PassivityFigures& figures() const { return figures_; }
  const PassivityParameters& parameters() const { return parameters_; }
  void reset();

 private:
  PassivityParameters parameters_;
  PassivityFigures figures_{};
  bool has_previous_ = false;
  Vector3 previous_x_{};
  Vector3 held_{};     // the force written at the previous tick
  Vector3 damper_{};   // its damper part
  double last_work_ = 0;
};

}  // namespace incise::haptics
