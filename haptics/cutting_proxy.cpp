#include "haptics/cutting_proxy.hpp"

#include <algorithm>
#include <cmath>

namespace incise::haptics {

namespace {

double dot3(const Vector3& a, const Vector3& b) { return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]; }

// The unit vector `from` turned towards the unit vector `to` by at most `angle` (rad).
Vector3 turn_towards(const Vector3& from, const Vector3& to, double angle) {
  const double c = std::clamp(dot3(from, to), -1.0, 1.0);
  if (std::acos(c) <= angle) return to;
  Vector3 across{to[0] - c * from[0], to[1] - c * from[1], to[2] - c * from[2]};
  double length = std::sqrt(dot3(across, across));
  if (length < 1e-12) {  // opposite: any axis across `from`
    across = std::abs(from[0]) < 0.9 ? Vector3{0, -from[2], from[1]} : Vector3{from[2], 0, -from[0]};
    length = std::sqrt(dot3(across, across));
  }
  Vector3 out;
  for (int i = 0; i < 3; ++i) out[i] = std::cos(angle) * from[i] + std::sin(angle) * across[i] / length;
  return out;
}

}  // namespace

Vector3 CuttingProxy::tick(const CuttingResistance& term, double level, const Vector3& x, double period_s) {
  const bool given = level > 0 && term.stiffness > 0;
  if (!given && !engaged_) return {};
  // The level held falls at most kFallRate; with none given the spring keeps its axis and
  // stiffness while it lets go.
  level_ = std::max(given ? level : 0.0, level_ - kFallRate * period_s);
  if (!(level_ > 0)) {
    engaged_ = false;
    level_ = 0;
    return {};
  }
  if (!engaged_) {
    front_ = x;  // a new cut starts unloaded where the hand is
    direction_ = term.direction;
    engaged_ = true;
  } else if (given) {
    direction_ = turn_towards(direction_, term.direction, kTurnRate * period_s);
  }
  if (given) stiffness_ = term.stiffness;
  const Vector3& d = direction_;
  double s = (x[0] - front_[0]) * d[0] + (x[1] - front_[1]) * d[1] + (x[2] - front_[2]) * d[2];
  if (s <= 0) return {};
  const double stretch = level_ / stiffness_;
  if (s > stretch) {
    for (int i = 0; i < 3; ++i) front_[i] += (s - stretch) * d[i];
    s = stretch;
  }
  const double magnitude = stiffness_ * s;
  return {-magnitude * d[0], -magnitude * d[1], -magnitude * d[2]};
}

BlendedCutting blend_cutting(std::span<const WeightedModel> models, const Vector3& x) {
  BlendedCutting out;
  double level = 0, strongest = -1;
  for (const WeightedModel& m : models) {
    const double part = m.weight * m.model->cutting.force * domain_weight(*m.model, x);
    level += part;
    if (part > strongest) {
      strongest = part;
      out.term = m.model->cutting;
    }
  }
  out.level = std::max(0.0, level);
  return out;
}

BlendedCutting blend_cutting(const ContactModel& model, const ContactModel* faded, double weight, const Vector3& x) {
  const WeightedModel both[] = {{&model, weight}, {faded, 1 - weight}};
  return blend_cutting(std::span<const WeightedModel>(both, faded ? 2 : 1), x);
}

}  // namespace incise::haptics
