// The stability sweep's thin-slice study (bench/stability.cpp says what it shows).
#include "bench/stability_sweep.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <sstream>
#include <string>
#include <vector>

namespace incise::bench::sweep {

// ---- The thin-slice study ------------------------------------------------------------------

// thin_slice under gravity with each rotation of the corotation: the slices hang from their
// attachment and should come to rest. Spontaneous motion shows as kinetic energy and drift
// that do not die out, and as a rise of the total energy (elastic + kinetic + gravitational),
// which a damped conservative model never has (implicit Euler and mass damping only dissipate).
struct SliceStudy {
  physics::EfgRotation rotation;
  double youngs_modulus = 0;
  double dt = 0;
  int steps = 0;
  bool finite = true;
  std::array<double, 2> late_speed{};  // rms particle speed over the last second, m/s, per slice
  std::array<double, 2> late_drift{};  // centroid motion over the last second, m, per slice
  std::array<double, 2> sag{};         // centroid displacement from rest at the end, m
  double energy_rise = 0;              // sum of the per-step rises of the total energy, J
  double energy_scale = 0;             // |total energy at the end - at the start|, J
};

const char* rotation_name(physics::EfgRotation rotation) {
  return rotation == physics::EfgRotation::shape_matching ? "shape_matching" : "deformation_gradient";
}

SliceStudy study_thin_slice(physics::EfgRotation rotation, double youngs_modulus, double dt,
                            double duration) {
  const Material material{youngs_modulus, 0.45, density};
  Body body = make_efg_body("thin_slice", material, rotation);
  DeformableModel& model = *body.model;
  const Vector& masses = model.lumped_masses();
  State state = body.initial;
  physics::WarmStart warm_start;
  SliceStudy study;
  study.rotation = rotation;
  study.youngs_modulus = youngs_modulus;
  study.dt = dt;
  const auto centroid = [&](const std::vector<int>& slice, const Vector& x) {
    Vec3 sum = Vec3::Zero();
    double mass = 0;
    for (int node : slice) sum += masses[node] * x.segment<3>(3 * node), mass += masses[node];
    return Vec3(sum / mass);
  };
  const auto total_energy = [&](const State& s) {
    return model.elastic_energy(s.positions) + physics::kinetic_energy(masses, s.velocities) -
           body.external.dot(s.positions);
  };
  const int steps = static_cast<int>(std::lround(duration / dt));
  const int late = static_cast<int>(std::lround(1.0 / dt));
  std::array<Vec3, 2> late_start{};
  std::array<double, 2> squared_speed{};
  std::array<int, 2> samples{};
  const double initial_energy = total_energy(state);
  double energy = initial_energy;
  for (int step = 0; step < steps; ++step) {
    const physics::StepReport report = physics::implicit_euler_step(
        model, state, body.fixed, body.external, {}, implicit_settings(dt), &warm_start);
    if (report.nonfinite) {
      study.finite = false;
      break;
    }
    study.steps = step + 1;
    const double next = total_energy(state);
    study.energy_rise += std::max(0.0, next - energy);
    energy = next;
    if (step == steps - late - 1) {
      for (size_t k = 0; k < 2; ++k) late_start[k] = centroid(body.slices[k], state.positions);
    }
    if (step >= steps - late) {
      for (size_t k = 0; k < 2; ++k) {
        for (int node : body.slices[k]) squared_speed[k] += state.velocities.segment<3>(3 * node).squaredNorm();
        samples[k] += static_cast<int>(body.slices[k].size());
      }
    }
  }
  study.energy_scale = std::abs(energy - initial_energy);
  for (size_t k = 0; k < 2; ++k) {
    const std::vector<int>& slice = body.slices[k];
    study.late_speed[k] = samples[k] ? std::sqrt(squared_speed[k] / samples[k]) : 0;
    study.late_drift[k] = (centroid(slice, state.positions) - late_start[k]).norm();
    study.sag[k] = (centroid(slice, state.positions) - centroid(slice, model.rest_positions())).norm();
  }
  return study;
}

std::string thin_slice_report(bool quick, std::ostream& progress) {
  const double duration = quick ? 3.0 : 6.0;
  const double dt = 1.0 / 60;
  std::ostringstream text;
  text << "Thin-slice study (thin_slice under gravity, nu 0.45, dt " << format(1e3 * dt, 3)
       << " ms, mass damping " << format(rayleigh_mass) << "/s, T = " << format(duration)
       << " s; slices: top one element thick, bottom two; late = the last second):\n";
  char line[320];
  std::snprintf(line, sizeof line, "  %-21s %8s %6s | %12s %12s %9s | %12s %12s %9s | %11s\n",
                "rotation", "E", "steps", "top v mm/s", "top drift mm", "top sag", "bot v mm/s",
                "bot drift mm", "bot sag", "E rise / dE");
  text << line;
  for (double youngs_modulus : {10e3, 100e3, 1e6}) {
    for (physics::EfgRotation rotation :
         {physics::EfgRotation::shape_matching, physics::EfgRotation::deformation_gradient}) {
      progress << "\rthin-slice study: " << rotation_name(rotation) << " E " << short_modulus(youngs_modulus)
               << "          " << std::flush;
      const SliceStudy s = study_thin_slice(rotation, youngs_modulus, dt, duration);
      std::snprintf(line, sizeof line,
                    "  %-21s %8s %6d | %12.4g %12.4g %9.4g | %12.4g %12.4g %9.4g | %11.3g%s\n",
                    rotation_name(rotation), short_modulus(youngs_modulus).c_str(), s.steps,
                    1e3 * s.late_speed[0], 1e3 * s.late_drift[0], 1e3 * s.sag[0],
                    1e3 * s.late_speed[1], 1e3 * s.late_drift[1], 1e3 * s.sag[1],
                    s.energy_scale > 0 ? s.energy_rise / s.energy_scale : 0.0,
                    s.finite ? "" : "  (non-finite: stopped)");
      text << line;
    }
  }
  progress << "\n";
  return text.str();
}


}  // namespace incise::bench::sweep
