#include "physics/promayon/seed_step.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>

namespace incise::physics {

std::string_view seed_scheme_name(SeedScheme s) { return s == SeedScheme::explicit_euler ? "explicit_euler" : "symplectic_euler"; }

std::optional<SeedScheme> seed_scheme_from_name(std::string_view name) {
  if (name == "explicit_euler") return SeedScheme::explicit_euler;
  if (name == "symplectic_euler") return SeedScheme::symplectic_euler;
  return std::nullopt;
}

double VolumeControl::at(double time) const {
  if (target.empty()) return rest_volume;
  if (time <= target.front().first) return target.front().second;
  if (time >= target.back().first) return target.back().second;
  const auto it = std::upper_bound(target.begin(), target.end(), time,
                                   [](double t, const std::pair<double, double>& e) { return t < e.first; });
  const auto& b = *it;
  const auto& a = *(it - 1);
  return a.second + (time - a.first) / (b.first - a.first) * (b.second - a.second);
}

bool apply_seed_constraints(State& state, const Vector& before_positions, const std::vector<std::uint8_t>& fixed,
                            double dt, const VolumeControl* volume, double end_time, SeedStepReport& report) {
  Vector x = state.positions;
  const Vector integrated = x;
  for (std::size_t i = 0; i < fixed.size(); ++i)
    if (fixed[i]) x.segment<3>(3 * static_cast<Eigen::Index>(i)) = before_positions.segment<3>(3 * static_cast<Eigen::Index>(i));
  if (volume) {
    report.volume_target = volume->at(end_time);
    if (volume->mode == VolumeMode::exact) {
      try {
        const VolumeProjection p = project_volume(x, volume->triangles, fixed, report.volume_target);
        report.lambda = p.lambda;
        report.volume = p.volume_after;
      } catch (const std::runtime_error&) {
        return false;
      }
    } else {
      report.volume = closed_volume(x, volume->triangles);
    }
  }
  Vector v = state.velocities + (x - integrated) / dt;
  for (std::size_t i = 0; i < fixed.size(); ++i)
    if (fixed[i]) v.segment<3>(3 * static_cast<Eigen::Index>(i)).setZero();
  if (!x.allFinite() || !v.allFinite()) return false;
  state.positions = std::move(x);
  state.velocities = std::move(v);
  return true;
}

double seed_step_limit(DeformableModel& model, const std::vector<std::uint8_t>& fixed) {
  const Vector& m = model.lumped_masses();
  const Eigen::Index n3 = 3 * m.size();
  model.update_rotations(model.rest_positions());
  Vector v(n3);
  for (Eigen::Index i = 0; i < n3; ++i) v[i] = 1 + 0.5 * std::sin(1.7 * static_cast<double>(i));  // deterministic start
  const auto clamp = [&](Vector& x) {
    for (std::size_t i = 0; i < fixed.size(); ++i)
      if (fixed[i]) x.segment<3>(3 * static_cast<Eigen::Index>(i)).setZero();
  };
  clamp(v);
  double lambda = 0;
  for (int it = 0; it < 300; ++it) {
    Vector kv = Vector::Zero(n3);
    model.add_stiffness_product(v, kv);
    clamp(kv);
    double mass_norm = 0;
    for (Eigen::Index i = 0; i < n3; ++i) mass_norm += m[i / 3] * v[i] * v[i];
    if (!(mass_norm > 0)) break;
    lambda = v.dot(kv) / mass_norm;  // Rayleigh quotient of (K, M)
    for (Eigen::Index i = 0; i < n3; ++i) v[i] = kv[i] / m[i / 3];
    v /= v.norm();
  }
  return lambda > 0 ? 2 / std::sqrt(lambda) : std::numeric_limits<double>::infinity();
}

SeedStepReport seed_explicit_step(DeformableModel& model, State& state, const std::vector<std::uint8_t>& fixed,
                                  const Vector& external, const std::vector<NodalSpring>& springs,
                                  const SeedStepSettings& settings, const VolumeControl* volume, double end_time) {
  const Eigen::Index n3 = state.positions.size();
  if (external.size() != n3 || state.velocities.size() != n3 || !(settings.dt > 0))
    throw std::invalid_argument("seed_explicit_step: sizes disagree or dt <= 0");
  SeedStepReport report;
  // 1. boundary conditions
  Vector v = state.velocities;
  for (std::size_t i = 0; i < fixed.size(); ++i)
    if (fixed[i]) v.segment<3>(3 * static_cast<Eigen::Index>(i)).setZero();
  // 2. forces (the model redistributes its reactions inside add_elastic_forces)
  const Vector& x = state.positions;
  model.update_rotations(x);
  const Vector& m = model.lumped_masses();
  Vector f = external - settings.damping * v;
  if (settings.mass_damping > 0)
    for (Eigen::Index i = 0; i < n3; ++i) f[i] -= settings.mass_damping * m[i / 3] * v[i];
  model.add_elastic_forces(x, f);
  if (model.has_damping()) {
    Vector damping = Vector::Zero(n3);
    model.add_damping_product(v, damping);
    f -= damping;
  }
  for (const NodalSpring& s : springs) f.segment<3>(3 * s.node) += s.force;
  if (volume && volume->mode == VolumeMode::penalty)
    add_volume_penalty_forces(x, volume->triangles, fixed, volume->at(end_time - settings.dt), volume->penalty_stiffness, f);
  // 3. integrate
  Vector a(n3);
  for (Eigen::Index i = 0; i < n3; ++i) a[i] = f[i] / m[i / 3];
  State next;
  if (settings.scheme == SeedScheme::explicit_euler) {
    next.positions = x + settings.dt * v;
    next.velocities = v + settings.dt * a;
  } else {
    next.velocities = v + settings.dt * a;
    next.positions = x + settings.dt * next.velocities;
  }
  // 4-6. local constraints, volume, velocity correction
  if (!next.positions.allFinite() || !next.velocities.allFinite() ||
      !apply_seed_constraints(next, x, fixed, settings.dt, volume, end_time, report)) {
    report.nonfinite = true;
    return report;
  }
  state = std::move(next);
  report.elastic_energy = model.elastic_energy(state.positions);
  for (Eigen::Index i = 0; i < n3; ++i) report.kinetic_energy += 0.5 * m[i / 3] * state.velocities[i] * state.velocities[i];
  return report;
}

}  // namespace incise::physics
