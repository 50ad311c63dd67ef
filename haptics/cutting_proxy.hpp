// The cutting resistance as the hand meets it at 1 kHz (ContactModel::cutting; Mahvash and
// Hayward 2004, "Haptic rendering of cutting: a fracture mechanics approach"): the tissue ahead
// of the edge is a spring of stiffness k along the blade's motion d, anchored at the crack
// front f. Each tick, with the hand at x and s = (x - f) . d,
//     s > F / k:  the tissue ruptures: the front advances to x - (F / k) d (cutting phase);
//     s <= 0:     the hand is behind the front: no force, the front stays (a crack does not heal);
// and the force is -k s d, at most F (the model's rupture level, weighted by the model's domain
// and by the blend between models). The force builds up over F / k of the hand's motion and
// follows it continuously, where a force that stepped with the hand's speed would jump by F at
// a stroke's start and end; the front only moves forward, so the hand can get back at most the
// energy it put into the spring (passive). The level the spring holds falls towards the one
// given at most kFallRate: physics hands the level over once a step, ramped per step in
// simulated time (HapticSession::publish), but its steps come unevenly in real time (a slow
// cut step, then a quick one or two: the fade of each model runs over the interval before it)
// and a stale model's domain fades as the hand leaves it, so the level given can fall faster
// than the session's ramp, and the loaded spring with it. A rising level needs no bound: the spring loads only with
// the hand's motion. When the level has fallen to zero the spring lets go, and the next cut
// starts unloaded at the hand; while it falls the spring keeps its axis. The direction the
// spring acts along turns towards each model's d at most kTurnRate: a blade that pressed down
// and then draws along would otherwise swap a loaded spring's axis in one tick (a jump of up
// to F).
#pragma once

#include <span>

#include "haptics/contact_model.hpp"
#include "haptics/model_fade.hpp"

namespace incise::haptics {

class CuttingProxy {
 public:
  static constexpr double kTurnRate = 5;   // rad/s
  static constexpr double kFallRate = 10;  // N/s: the session's ramp per step, in the hand's time
  // The force on the hand (N) at x for the term (direction d, stiffness k) at rupture level
  // `level` (N, >= 0: the term's force times its weights; the spring's falls towards it at
  // most kFallRate period_s a tick).
  Vector3 tick(const CuttingResistance& term, double level, const Vector3& x, double period_s);
  bool engaged() const { return engaged_; }
  double level() const { return level_; }  // N, the level the spring holds
  const Vector3& front() const { return front_; }
  const Vector3& direction() const { return direction_; }

 private:
  bool engaged_ = false;
  double level_ = 0;
  double stiffness_ = 0;
  Vector3 front_{};
  Vector3 direction_{1, 0, 0};  // unit, turning towards the model's
};

// The term rendered while the newest model fades in over its origin (model_fade.hpp; newest
// first): the levels weighted by each model's domain at x and by the blend, the direction of
// the strongest part (the newest's on a tie).
struct BlendedCutting {
  CuttingResistance term;
  double level = 0;
};
BlendedCutting blend_cutting(std::span<const WeightedModel> models, const Vector3& x);
// The same for `model` fading in over `faded` (weight w of the new one; faded null: none).
BlendedCutting blend_cutting(const ContactModel& model, const ContactModel* faded, double weight, const Vector3& x);

}  // namespace incise::haptics
