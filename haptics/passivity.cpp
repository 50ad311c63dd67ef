#include "haptics/passivity.hpp"

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <string>

#include "haptics/haptic_loop.hpp"  // clamp_force

namespace incise::haptics {

namespace {
bool finite(const Vector3& v) { return std::isfinite(v[0]) && std::isfinite(v[1]) && std::isfinite(v[2]); }
double dot(const Vector3& a, const Vector3& b) { return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]; }
}  // namespace

void validate(const PassivityParameters& parameters) {
  require_finite(parameters.max_damping, "passivity.max_damping");
  if (parameters.max_damping < 0)
    throw std::invalid_argument("passivity.max_damping " + std::to_string(parameters.max_damping) + " N s/m is negative");
  require_finite(parameters.max_step, "passivity.max_step");
  if (parameters.max_step < 0)
    throw std::invalid_argument("passivity.max_step " + std::to_string(parameters.max_step) + " N is negative");
}

PassivityController::PassivityController(PassivityParameters parameters) : parameters_(parameters) {
  validate(parameters_);
}

void PassivityController::reset() {
  figures_ = {};
  has_previous_ = false;
  previous_x_ = held_ = damper_ = Vector3{};
  last_work_ = 0;
}

Vector3 PassivityController::tick(const Vector3& x, const Vector3& velocity, const Vector3& force, double period_s,
                                  double max_force, bool render) {
  // The observer: the work of the force held over the interval that just ended.
  last_work_ = 0;
  if (has_previous_ && finite(x)) {
    Vector3 displacement;
    for (int i = 0; i < 3; ++i) displacement[i] = x[i] - previous_x_[i];
    const double work = dot(held_, displacement);
    const double damper_work = dot(damper_, displacement);
    if (std::isfinite(work) && std::isfinite(damper_work)) {
      last_work_ = work;
      figures_.device_energy_J += work;
      figures_.dissipated_J -= damper_work;
    }
  }
  if (finite(x)) {
    previous_x_ = x;
    has_previous_ = true;
  }

  // The controller: the damper that would take the whole excess over the predicted displacement,
  // within max_damping, then moved from the last one by at most max_step.
  const Vector3 rendered = render && finite(force) ? force : Vector3{};
  Vector3 wanted{};
  const double excess = figures_.device_energy_J;
  Vector3 predicted{};
  if (finite(velocity))
    for (int i = 0; i < 3; ++i) predicted[i] = velocity[i] * period_s;
  const double d2 = dot(predicted, predicted);
  if (render && parameters_.enabled && excess > 0 && d2 > 0 && period_s > 0) {
    const double c = std::min(excess / d2, parameters_.max_damping / period_s);  // N/m; c T is the damping
    for (int i = 0; i < 3; ++i) wanted[i] = -c * predicted[i];
  }
  // Towards the wanted damper by at most max_step; never beyond max_damping at this velocity
  // (a damper is bounded by its velocity, whatever it was a tick ago).
  Vector3 damper;
  for (int i = 0; i < 3; ++i) damper[i] = wanted[i] - damper_[i];
  const double step_size = std::sqrt(dot(damper, damper));
  const double scale = step_size > parameters_.max_step ? parameters_.max_step / step_size : 1.0;
  for (int i = 0; i < 3; ++i) damper[i] = damper_[i] + scale * damper[i];
  const double bound = parameters_.max_damping * std::sqrt(dot(velocity, velocity));
  const double size = std::sqrt(dot(damper, damper));
  if (!(size <= bound)) {
    const double shrink = bound > 0 && std::isfinite(bound) ? bound / size : 0.0;
    for (double& f : damper) f *= shrink;
  }
  Vector3 out{};
  if (render)
    for (int i = 0; i < 3; ++i) out[i] = rendered[i] + damper[i];
  out = clamp_force(out, max_force);
  for (int i = 0; i < 3; ++i) damper_[i] = out[i] - rendered[i];
  if (dot(damper_, damper_) > 0) ++figures_.ticks_acted;
  held_ = out;
  return out;
}

}  // namespace incise::haptics
