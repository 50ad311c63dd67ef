// The needle's force as the hand meets it at 1 kHz (ContactModel::needle; seed 002 §2.3 renders
// the needle's resistance as friction and a lateral constraint). With the hand at x, the needle's
// axis a and its line point l (NeedleResistance):
//   - across the shaft, the tissue's grip: -k (I - a a^T)(x - l), a spring, so it gives back
//     what the hand put in;
//   - along it, friction as a spring with slip (Hayward and Armstrong's elasto-plastic model, the
//     cutting proxy's two phases): an anchor on the axis, s = (x - anchor) . a, the force -k s a
//     while -F_out <= k s <= F_in; beyond, the anchor slides with the hand so that k s stays at
//     F_in (pushing in: cutting and friction) or -F_out (pulling out: friction only). The anchor
//     only follows the hand, so at a constant k the spring returns at most what it stored. The
//     state kept is the load k s (advanced by k times the hand's motion along the axis), so a
//     model whose k differs (a node entering or leaving the tissue) changes no force at once;
//     what such a change could give back the loop's passivity controller takes.
// Both are weighted by the model's domain and blended between models as the contacts are (the
// lateral forces of the two models mixed by the blend's weight, the axial levels likewise), so a
// new publication is faded in; a level that falls lets the spring go (the anchor moves to the
// hand), one that goes to zero (the needle out) disengages it.
#pragma once

#include <span>

#include "haptics/contact_model.hpp"
#include "haptics/model_fade.hpp"

namespace incise::haptics {

class NeedleProxy {
 public:
  // The force on the hand (N) at x of the needle term blended between the models of a fade
  // (model_fade.hpp: the newest first, then its origin's).
  Vector3 tick(std::span<const WeightedModel> models, const Vector3& x);
  // The same for `model` fading in over `faded` (weight w of the new model; faded null: none).
  Vector3 tick(const ContactModel& model, const ContactModel* faded, double weight, const Vector3& x);
  bool engaged() const { return engaged_; }
  double load() const { return load_; }  // N along the axis, positive resisting insertion

 private:
  bool engaged_ = false;
  Vector3 last_{};   // the hand at the last tick
  double load_ = 0;  // k s, between -F_out and F_in
};

// The lateral spring of one model at x (unweighted): -k (I - a a^T)(x - l); zero out of the tissue.
Vector3 needle_lateral_force(const NeedleResistance& needle, const Vector3& x);

}  // namespace incise::haptics
