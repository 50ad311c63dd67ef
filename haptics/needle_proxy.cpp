#include "haptics/needle_proxy.hpp"

#include <algorithm>

namespace incise::haptics {

namespace {
double dot3(const Vector3& a, const Vector3& b) { return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]; }
}  // namespace

Vector3 needle_lateral_force(const NeedleResistance& needle, const Vector3& x) {
  if (!(needle.stiffness > 0)) return {};
  const Vector3& a = needle.axis;
  Vector3 off{x[0] - needle.line[0], x[1] - needle.line[1], x[2] - needle.line[2]};
  const double along = dot3(off, a);
  return {-needle.stiffness * (off[0] - along * a[0]), -needle.stiffness * (off[1] - along * a[1]),
          -needle.stiffness * (off[2] - along * a[2])};
}

Vector3 NeedleProxy::tick(const ContactModel& model, const ContactModel* faded, double weight, const Vector3& x) {
  const double now = weight * domain_weight(model, x);
  const double before = faded ? (1 - weight) * domain_weight(*faded, x) : 0.0;
  const NeedleResistance& n = model.needle;
  const NeedleResistance* f = faded ? &faded->needle : nullptr;
  Vector3 force = needle_lateral_force(n, x);
  for (int i = 0; i < 3; ++i) force[i] *= now;
  if (f) {
    const Vector3 old = needle_lateral_force(*f, x);
    for (int i = 0; i < 3; ++i) force[i] += before * old[i];
  }
  // The axial spring: the new model's axis and stiffness (the faded one's while the new one is
  // out of the tissue), the levels blended.
  const NeedleResistance& term = n.stiffness > 0 || !f ? n : *f;
  const double insert = now * n.insert_force + (f ? before * f->insert_force : 0.0);
  const double retract = now * n.retract_force + (f ? before * f->retract_force : 0.0);
  if (!(term.stiffness > 0) || !(insert > 0 || retract > 0)) {
    engaged_ = false;
    return force;
  }
  const Vector3& a = term.axis;
  if (!engaged_) {
    last_ = x;  // the needle enters unloaded where the hand is
    load_ = 0;
    engaged_ = true;
  }
  // The spring's load follows the hand's motion along the axis at the model's stiffness, held
  // between the levels: a stiffness that changes between models (a node entering the tissue)
  // changes how fast the load builds, never the load itself.
  const double moved = dot3({x[0] - last_[0], x[1] - last_[1], x[2] - last_[2]}, a);
  load_ = std::clamp(load_ + term.stiffness * moved, -retract, insert);
  last_ = x;
  for (int i = 0; i < 3; ++i) force[i] -= load_ * a[i];
  return force;
}

}  // namespace incise::haptics
