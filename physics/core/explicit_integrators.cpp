#include "physics/core/explicit_integrators.hpp"

#include <array>
#include <cmath>
#include <sstream>
#include <stdexcept>
#include <string>
#include <utility>

#include "physics/core/implicit_euler.hpp"

namespace incise::physics {

namespace {

using Index = Eigen::Index;

constexpr std::array<std::pair<ExplicitScheme, std::string_view>, 5> scheme_names{{
    {ExplicitScheme::explicit_euler, "explicit_euler"},
    {ExplicitScheme::midpoint, "rk2"},
    {ExplicitScheme::runge_kutta4, "rk4"},
    {ExplicitScheme::verlet, "verlet"},
    {ExplicitScheme::velocity_verlet, "velocity_verlet"},
}};

// The right-hand side of the first-order system x' = v, v' = a(x, v) for one step: the
// model, the constraints and the loads, with the checks every scheme shares.
class Dynamics {
 public:
  Dynamics(const char* scheme, DeformableModel& model, const State& state,
           const std::vector<uint8_t>& fixed_nodes, const Vector& external_forces,
           const ExplicitSettings& settings)
      : model_(model), fixed_(fixed_nodes), external_(external_forces), settings_(settings) {
    const int nodes = model.node_count();
    const Index size = 3 * static_cast<Index>(nodes);
    auto fail = [scheme](const std::string& what) {
      throw std::invalid_argument(std::string(scheme) + ": " + what);
    };
    if (state.positions.size() != size || state.velocities.size() != size) {
      fail("state has " + std::to_string(state.positions.size()) + " positions and " +
           std::to_string(state.velocities.size()) + " velocities, the model needs " +
           std::to_string(size));
    }
    if (external_forces.size() != size) {
      fail("external_forces has " + std::to_string(external_forces.size()) +
           " entries, expected " + std::to_string(size));
    }
    if (!fixed_nodes.empty() && static_cast<int>(fixed_nodes.size()) != nodes) {
      fail("fixed_nodes has " + std::to_string(fixed_nodes.size()) + " entries, expected " +
           std::to_string(nodes));
    }
    if (!(settings.dt > 0.0) || !std::isfinite(settings.dt)) fail("dt must be positive");
    if (!std::isfinite(settings.rayleigh_mass)) fail("rayleigh_mass must be finite");
  }

  // a = M^-1 (f_elastic(x) + f_external) - alpha v, zero on fixed nodes. Returns false (a
  // untouched) if x or v is not finite, before the model sees them.
  bool acceleration(const Vector& x, const Vector& v, Vector& a) {
    if (!x.allFinite() || !v.allFinite()) return false;
    model_.update_rotations(x);
    a = external_;
    model_.add_elastic_forces(x, a);
    if (settings_.model_damping && model_.has_damping()) {
      Vector damping = Vector::Zero(a.size());
      model_.add_damping_product(v, damping);
      a -= damping;
    }
    ++evaluations_;
    const Vector& masses = model_.lumped_masses();
    const double alpha = settings_.rayleigh_mass;
    for (Index node = 0; node < masses.size(); ++node) {
      a.segment<3>(3 * node) = a.segment<3>(3 * node) / masses[node] - alpha * v.segment<3>(3 * node);
    }
    zero_fixed(a);
    return a.allFinite();
  }

  void zero_fixed(Vector& values) const {
    for (size_t node = 0; node < fixed_.size(); ++node) {
      if (fixed_[node] != 0) values.segment<3>(3 * static_cast<Index>(node)).setZero();
    }
  }

  // Fixed nodes keep their old position bitwise (x + dt * 0 equals x, kept explicit so that
  // rounding in a weighted stage sum cannot move them).
  void restore_fixed(const Vector& old_positions, Vector& positions) const {
    for (size_t node = 0; node < fixed_.size(); ++node) {
      if (fixed_[node] != 0) {
        const Index offset = 3 * static_cast<Index>(node);
        positions.segment<3>(offset) = old_positions.segment<3>(offset);
      }
    }
  }

  // Accepts (x, v) into the state if they and their energies are finite; fills the report.
  ExplicitStepReport finish(State& state, Vector& positions, Vector& velocities) {
    ExplicitStepReport report;
    report.force_evaluations = evaluations_;
    restore_fixed(state.positions, positions);
    zero_fixed(velocities);
    if (!positions.allFinite() || !velocities.allFinite()) return reject();
    report.elastic_energy = model_.elastic_energy(positions);
    report.kinetic_energy = kinetic_energy(model_.lumped_masses(), velocities);
    if (!std::isfinite(report.elastic_energy) || !std::isfinite(report.kinetic_energy)) {
      return reject();
    }
    state.positions.swap(positions);
    state.velocities.swap(velocities);
    return report;
  }

  ExplicitStepReport reject() const {
    ExplicitStepReport report;
    report.nonfinite = true;
    report.force_evaluations = evaluations_;
    return report;
  }

  double dt() const { return settings_.dt; }

 private:
  DeformableModel& model_;
  const std::vector<uint8_t>& fixed_;
  const Vector& external_;
  const ExplicitSettings& settings_;
  int evaluations_ = 0;
};

// Velocities of fixed nodes are zero for the whole step, whatever the State held.
Vector free_velocities(const Dynamics& dynamics, const Vector& velocities) {
  Vector v = velocities;
  dynamics.zero_fixed(v);
  return v;
}

}  // namespace

std::string_view explicit_scheme_name(ExplicitScheme scheme) {
  for (const auto& [value, name] : scheme_names) {
    if (value == scheme) return name;
  }
  return "unknown";
}

std::optional<ExplicitScheme> explicit_scheme_from_name(std::string_view name) {
  for (const auto& [value, known] : scheme_names) {
    if (known == name) return value;
  }
  return std::nullopt;
}

ExplicitStepReport explicit_euler_step(DeformableModel& model, State& state,
                                       const std::vector<uint8_t>& fixed_nodes,
                                       const Vector& external_forces,
                                       const ExplicitSettings& settings) {
  Dynamics dynamics("explicit_euler_step", model, state, fixed_nodes, external_forces, settings);
  const double dt = dynamics.dt();
  const Vector v = free_velocities(dynamics, state.velocities);
  Vector a;
  if (!dynamics.acceleration(state.positions, v, a)) return dynamics.reject();
  Vector positions = state.positions + dt * v;
  Vector velocities = v + dt * a;
  return dynamics.finish(state, positions, velocities);
}

ExplicitStepReport midpoint_step(DeformableModel& model, State& state,
                                 const std::vector<uint8_t>& fixed_nodes,
                                 const Vector& external_forces, const ExplicitSettings& settings) {
  Dynamics dynamics("midpoint_step", model, state, fixed_nodes, external_forces, settings);
  const double dt = dynamics.dt();
  const Vector& x = state.positions;
  const Vector v = free_velocities(dynamics, state.velocities);
  Vector a;
  if (!dynamics.acceleration(x, v, a)) return dynamics.reject();
  const Vector middle_velocity = v + 0.5 * dt * a;
  Vector middle_acceleration;
  if (!dynamics.acceleration(x + 0.5 * dt * v, middle_velocity, middle_acceleration)) {
    return dynamics.reject();
  }
  Vector positions = x + dt * middle_velocity;
  Vector velocities = v + dt * middle_acceleration;
  return dynamics.finish(state, positions, velocities);
}

ExplicitStepReport runge_kutta4_step(DeformableModel& model, State& state,
                                     const std::vector<uint8_t>& fixed_nodes,
                                     const Vector& external_forces,
                                     const ExplicitSettings& settings) {
  Dynamics dynamics("runge_kutta4_step", model, state, fixed_nodes, external_forces, settings);
  const double dt = dynamics.dt();
  const Vector& x = state.positions;
  // Stage k: slope of x is v_k, slope of v is a_k = a(x_k, v_k).
  const Vector v1 = free_velocities(dynamics, state.velocities);
  Vector a1, a2, a3, a4;
  if (!dynamics.acceleration(x, v1, a1)) return dynamics.reject();
  const Vector v2 = v1 + 0.5 * dt * a1;
  if (!dynamics.acceleration(x + 0.5 * dt * v1, v2, a2)) return dynamics.reject();
  const Vector v3 = v1 + 0.5 * dt * a2;
  if (!dynamics.acceleration(x + 0.5 * dt * v2, v3, a3)) return dynamics.reject();
  const Vector v4 = v1 + dt * a3;
  if (!dynamics.acceleration(x + dt * v3, v4, a4)) return dynamics.reject();
  Vector positions = x + (dt / 6.0) * (v1 + 2.0 * v2 + 2.0 * v3 + v4);
  Vector velocities = v1 + (dt / 6.0) * (a1 + 2.0 * a2 + 2.0 * a3 + a4);
  return dynamics.finish(state, positions, velocities);
}

ExplicitStepReport verlet_step(DeformableModel& model, State& state,
                               const std::vector<uint8_t>& fixed_nodes,
                               const Vector& external_forces, const ExplicitSettings& settings,
                               VerletHistory& history) {
  Dynamics dynamics("verlet_step", model, state, fixed_nodes, external_forces, settings);
  const double dt = dynamics.dt();
  const Vector& x = state.positions;
  // The lagged velocity: the central difference at t - dt (or the initial velocity).
  const Vector lagged_velocity = free_velocities(dynamics, state.velocities);
  Vector a;
  if (!dynamics.acceleration(x, lagged_velocity, a)) return dynamics.reject();

  const bool history_valid = history.previous_positions.size() == x.size() &&
                             history.time_step == dt && history.previous_positions.allFinite();
  Vector previous = history_valid ? history.previous_positions
                                  : Vector(x - dt * lagged_velocity + 0.5 * dt * dt * a);
  dynamics.restore_fixed(x, previous);

  Vector positions = 2.0 * x - previous + dt * dt * a;
  Vector velocities = (positions - previous) / (2.0 * dt);
  Vector old_positions = x;
  ExplicitStepReport report = dynamics.finish(state, positions, velocities);
  if (!report.nonfinite) {
    history.previous_positions = std::move(old_positions);
    history.time_step = dt;
  }
  return report;
}

ExplicitStepReport velocity_verlet_step(DeformableModel& model, State& state,
                                        const std::vector<uint8_t>& fixed_nodes,
                                        const Vector& external_forces,
                                        const ExplicitSettings& settings) {
  Dynamics dynamics("velocity_verlet_step", model, state, fixed_nodes, external_forces, settings);
  const double dt = dynamics.dt();
  const Vector& x = state.positions;
  const Vector v = free_velocities(dynamics, state.velocities);
  Vector a;
  if (!dynamics.acceleration(x, v, a)) return dynamics.reject();
  Vector positions = x + dt * v + (0.5 * dt * dt) * a;
  dynamics.restore_fixed(x, positions);
  Vector next_acceleration;
  if (!dynamics.acceleration(positions, v + dt * a, next_acceleration)) return dynamics.reject();
  Vector velocities = v + (0.5 * dt) * (a + next_acceleration);
  return dynamics.finish(state, positions, velocities);
}

ExplicitStepReport explicit_step(ExplicitScheme scheme, DeformableModel& model, State& state,
                                 const std::vector<uint8_t>& fixed_nodes,
                                 const Vector& external_forces, const ExplicitSettings& settings,
                                 VerletHistory* history) {
  // A model that knows its stability bound (a mass-spring network's 2 sqrt(m_min / k_node_max),
  // the constraint particles' min 2 sqrt(m_i / k_i))
  // refuses a step beyond it rather than blowing up a few steps later.
  if (settings.dt > model.explicit_step_limit()) {
    std::ostringstream out;
    out.precision(4);
    out << "explicit_step: dt " << settings.dt << " s is beyond this model's explicit stability bound "
        << model.explicit_step_limit() << " s (about 2 sqrt(m / k) on its stiffest node); take dt under it or implicit Euler";
    throw std::invalid_argument(out.str());
  }
  switch (scheme) {
    case ExplicitScheme::explicit_euler:
      return explicit_euler_step(model, state, fixed_nodes, external_forces, settings);
    case ExplicitScheme::midpoint:
      return midpoint_step(model, state, fixed_nodes, external_forces, settings);
    case ExplicitScheme::runge_kutta4:
      return runge_kutta4_step(model, state, fixed_nodes, external_forces, settings);
    case ExplicitScheme::verlet:
      if (history == nullptr) {
        throw std::invalid_argument("explicit_step: Stoermer Verlet needs a VerletHistory");
      }
      return verlet_step(model, state, fixed_nodes, external_forces, settings, *history);
    case ExplicitScheme::velocity_verlet:
      return velocity_verlet_step(model, state, fixed_nodes, external_forces, settings);
  }
  throw std::invalid_argument("explicit_step: unknown scheme");
}

}  // namespace incise::physics
