#include "haptics/contact_model.hpp"

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <string>

namespace incise::haptics {

namespace {
void require_finite_vector(const Vector3& v, const std::string& what) {
  for (int i = 0; i < 3; ++i) require_finite(v[i], what + "[" + std::to_string(i) + "]");
}
double dot(const Vector3& a, const Vector3& b) { return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]; }
}  // namespace

void validate(const ContactModel& model) {
  if (model.count < 0 || model.count > ContactModel::kCapacity)
    throw std::invalid_argument("ContactModel.count " + std::to_string(model.count) + " is outside [0, " +
                                std::to_string(ContactModel::kCapacity) + "]");
  for (int i = 0; i < model.count; ++i) {
    const ContactPoint& c = model.contacts[i];
    const std::string at = "ContactModel.contacts[" + std::to_string(i) + "]";
    require_finite_vector(c.point, at + ".point");
    require_finite_vector(c.normal, at + ".normal");
    require_finite(c.reach, at + ".reach");
    require_finite(c.stiffness, at + ".stiffness");
    require_finite(c.compliance, at + ".compliance");
    const double n = std::sqrt(dot(c.normal, c.normal));
    if (std::abs(n - 1) > 1e-6) throw std::invalid_argument(at + ".normal is not unit (|n| = " + std::to_string(n) + ")");
    if (!(c.stiffness > 0)) throw std::invalid_argument(at + ".stiffness " + std::to_string(c.stiffness) + " is not > 0");
    if (!(c.compliance >= 0))
      throw std::invalid_argument(at + ".compliance " + std::to_string(c.compliance) + " is not >= 0");
  }
  const CuttingResistance& cut = model.cutting;
  require_finite_vector(cut.direction, "ContactModel.cutting.direction");
  require_finite(cut.force, "ContactModel.cutting.force");
  require_finite(cut.stiffness, "ContactModel.cutting.stiffness");
  if (!(cut.force >= 0)) throw std::invalid_argument("ContactModel.cutting.force " + std::to_string(cut.force) + " is not >= 0");
  if (!(cut.stiffness > 0))
    throw std::invalid_argument("ContactModel.cutting.stiffness " + std::to_string(cut.stiffness) + " is not > 0");
  const double length = std::sqrt(dot(cut.direction, cut.direction));
  if (cut.force > 0 && std::abs(length - 1) > 1e-6)
    throw std::invalid_argument("ContactModel.cutting.direction is not unit (|d| = " + std::to_string(length) + ")");
  const NeedleResistance& needle = model.needle;
  require_finite_vector(needle.axis, "ContactModel.needle.axis");
  require_finite_vector(needle.line, "ContactModel.needle.line");
  require_finite(needle.insert_force, "ContactModel.needle.insert_force");
  require_finite(needle.retract_force, "ContactModel.needle.retract_force");
  require_finite(needle.stiffness, "ContactModel.needle.stiffness");
  if (!(needle.insert_force >= 0) || !(needle.retract_force >= 0) || !(needle.stiffness >= 0))
    throw std::invalid_argument("ContactModel.needle: insert_force " + std::to_string(needle.insert_force) + ", retract_force " +
                                std::to_string(needle.retract_force) + " and stiffness " + std::to_string(needle.stiffness) +
                                " must be >= 0");
  const double axis = std::sqrt(dot(needle.axis, needle.axis));
  if (needle.stiffness > 0 && std::abs(axis - 1) > 1e-6)
    throw std::invalid_argument("ContactModel.needle.axis is not unit (|a| = " + std::to_string(axis) + ")");
  require_finite_vector(model.linearised_at, "ContactModel.linearised_at");
  require_finite(model.valid_radius, "ContactModel.valid_radius");
  if (!(model.valid_radius >= 0))
    throw std::invalid_argument("ContactModel.valid_radius " + std::to_string(model.valid_radius) + " is not >= 0");
  require_finite_vector(model.proxy_position, "ContactModel.proxy_position");
  require_finite_vector(model.proxy_velocity, "ContactModel.proxy_velocity");
}

double domain_weight(const ContactModel& model, const Vector3& x) {
  if (!(model.valid_radius > 0)) return 1;
  const Vector3 away{x[0] - model.linearised_at[0], x[1] - model.linearised_at[1], x[2] - model.linearised_at[2]};
  const double d = std::sqrt(dot(away, away));
  return std::clamp(2 * (model.valid_radius - d) / model.valid_radius, 0.0, 1.0);
}

Vector3 contact_force(const ContactModel& model, const Vector3& x, const Vector3& x_dot, double period_s) {
  const double weight = domain_weight(model, x);
  if (weight == 0) return {};
  Vector3 force{};
  const int count = model.count < 0 ? 0 : (model.count > ContactModel::kCapacity ? ContactModel::kCapacity : model.count);
  for (int i = 0; i < count; ++i) {
    const ContactPoint& c = model.contacts[i];
    const Vector3 offset{x[0] - c.point[0], x[1] - c.point[1], x[2] - c.point[2]};
    const double depth = c.reach - dot(offset, c.normal);
    if (depth <= 0) continue;
    const double k_eff = 1.0 / (1.0 / c.stiffness + c.compliance);
    const double normal_velocity = dot(x_dot, c.normal);
    double magnitude = k_eff * depth - k_eff * period_s * normal_velocity;
    if (magnitude < 0) magnitude = 0;
    for (int a = 0; a < 3; ++a) force[a] += weight * magnitude * c.normal[a];
  }
  return force;
}

}  // namespace incise::haptics
