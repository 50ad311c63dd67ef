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
  const WeightedModel both[] = {{&model, weight}, {faded, 1 - weight}};
  return tick(std::span<const WeightedModel>(both, faded ? 2 : 1), x);
}

Vector3 NeedleProxy::tick(std::span<const WeightedModel> models, const Vector3& x) {
  Vector3 force{};
  double insert = 0, retract = 0;
  // The axial spring: the newest model's axis and stiffness (the next newest in the tissue
  // while it is out), the levels blended.
  const NeedleResistance* in_tissue = nullptr;
  for (const WeightedModel& m : models) {
    const double share = m.weight * domain_weight(*m.model, x);
    const NeedleResistance& n = m.model->needle;
    const Vector3 lateral = needle_lateral_force(n, x);
    for (int i = 0; i < 3; ++i) force[i] += share * lateral[i];
    insert += share * n.insert_force;
    retract += share * n.retract_force;
    if (!in_tissue && n.stiffness > 0) in_tissue = &n;
  }
  const NeedleResistance& term = in_tissue ? *in_tissue : models.front().model->needle;
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
