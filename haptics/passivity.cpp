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

Vector3 PassivityController::tick(const Vector3& x, const Vector3& force, double period_s, double max_force, bool render) {
  // The observer: the work of the force held over the interval that just ended.
  Vector3 displacement{};
  last_work_ = 0;
  if (has_previous_ && finite(x)) {
    for (int i = 0; i < 3; ++i) displacement[i] = x[i] - previous_x_[i];
    const double work = dot(held_, displacement);
    if (std::isfinite(work)) {
      last_work_ = work;
      figures_.device_energy_J += work;
      figures_.dissipated_J -= dot(damper_, displacement);
    }
  }
  if (finite(x)) {
    previous_x_ = x;
    has_previous_ = true;
  }

  // The controller: a damper that would take the whole excess over a displacement like the last.
  const Vector3 rendered = render && finite(force) ? force : Vector3{};
  Vector3 out = rendered;
  damper_ = Vector3{};
  const double excess = figures_.device_energy_J;
  const double d2 = dot(displacement, displacement);
  if (render && parameters_.enabled && excess > 0 && d2 > 0 && period_s > 0) {
    // Force = -c d with c = E / |d|^2 N/m, i.e. damping c T N s/m, capped at max_damping.
    const double c = std::min(excess / d2, parameters_.max_damping / period_s);
    for (int i = 0; i < 3; ++i) out[i] -= c * displacement[i];
    out = clamp_force(out, max_force);
    for (int i = 0; i < 3; ++i) damper_[i] = out[i] - rendered[i];
    ++figures_.ticks_acted;
  }
  held_ = out;
  return out;
}

}  // namespace incise::haptics
