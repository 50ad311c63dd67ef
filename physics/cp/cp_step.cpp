#include "physics/cp/cp_step.hpp"

#include <algorithm>
#include <cmath>

namespace incise::physics {

Vector inverse_masses(const Vector& masses, const std::vector<std::uint8_t>& fixed) {
  Vector w = masses.cwiseInverse();
  for (std::size_t i = 0; i < fixed.size(); ++i)
    if (fixed[i]) w[static_cast<Eigen::Index>(i)] = 0;
  return w;
}

StretchReport limit_stretch(const std::vector<StretchEdge>& edges, const Vector& w, const StretchLimiter& limiter,
                            Vector& q, std::vector<std::uint8_t>& moved) {
  StretchReport report;
  moved.assign(static_cast<std::size_t>(w.size()), 0);
  if (!limiter.enabled || limiter.stiffness <= 0) return report;
  const int n = std::max(1, limiter.iterations);
  const double k = 1.0 - std::pow(1.0 - limiter.stiffness, 1.0 / n);  // eq. 1.40
  for (int iteration = 0; iteration < n; ++iteration)
    for (const StretchEdge& e : edges) {
      const double wa = w[e.a], wb = w[e.b];
      if (wa + wb <= 0) continue;
      const Vec3 d = q.segment<3>(3 * e.a) - q.segment<3>(3 * e.b);
      const double length = d.norm();
      const double limit = limiter.alpha * e.rest;
      if (!(length > limit)) continue;
      // eq. 3.10: dx_i = -k' w_i / (w_i + w_j) (|x_ij| - alpha D0) x_ij / |x_ij|, dx_j opposite.
      const Vec3 s = (k * (length - limit) / ((wa + wb) * length)) * d;
      q.segment<3>(3 * e.a) -= wa * s;
      q.segment<3>(3 * e.b) += wb * s;
      moved[e.a] |= wa > 0;
      moved[e.b] |= wb > 0;
      ++report.projections;
    }
  for (std::uint8_t m : moved) report.particles += m;
  return report;
}

CpStepReport constraint_particles_step(ConstraintParticles& model, State& state, const std::vector<std::uint8_t>& fixed,
                                       const Vector& external, const CpStepSettings& settings, VerletHistory& history) {
  CpStepReport report;
  const State before = state;
  ExplicitSettings explicit_settings;
  explicit_settings.dt = settings.dt;
  explicit_settings.rayleigh_mass = settings.rayleigh_mass;
  explicit_settings.model_damping = true;
  report.integrator = explicit_step(settings.scheme, model, state, fixed, external, explicit_settings, &history);
  if (report.integrator.nonfinite) {
    report.nonfinite = true;
    return report;
  }
  Vector& q = state.positions;
  std::vector<std::uint8_t> moved;
  report.stretch = limit_stretch(model.edges(), inverse_masses(model.lumped_masses(), fixed), settings.limiter, q, moved);
  if (settings.floor_z) {
    for (std::size_t i = 0; i < moved.size(); ++i) {
      const Eigen::Index z = 3 * static_cast<Eigen::Index>(i) + 2;
      if ((fixed.empty() || !fixed[i]) && q[z] < *settings.floor_z) {
        q[z] = *settings.floor_z;
        state.velocities[z] = std::max(0.0, state.velocities[z]);
        ++report.floor_contacts;
      }
    }
  }
  // Alg. 3.2: v = (q - x) / dt for the particles the projection moved, the others keep theirs.
  for (std::size_t i = 0; i < moved.size(); ++i)
    if (moved[i]) {
      const Eigen::Index at = 3 * static_cast<Eigen::Index>(i);
      state.velocities.segment<3>(at) = (q.segment<3>(at) - before.positions.segment<3>(at)) / settings.dt;
    }
  if (!q.allFinite() || !state.velocities.allFinite()) {
    state = before;
    report.nonfinite = true;
    return report;
  }
  report.inverted_tets = model.inverted_tets(q);
  return report;
}

RelaxReport relax(ConstraintParticles& model, State& state, const std::vector<std::uint8_t>& fixed, const Vector& external,
                  const CpStepSettings& settings, const RelaxSettings& relax_settings) {
  RelaxReport report;
  double previous = model.elastic_energy(state.positions);
  int calm = 0;
  while (report.steps < relax_settings.max_steps) {
    const CpStepReport step = constraint_particles_step(model, state, fixed, external, settings, model.verlet_history());
    ++report.steps;
    if (step.nonfinite) {
      report.nonfinite = true;
      break;
    }
    report.energy = model.elastic_energy(state.positions);
    const double change = std::abs(report.energy - previous);
    previous = report.energy;
    calm = change < relax_settings.tolerance ? calm + 1 : 0;
    if (calm >= relax_settings.calm_steps) {
      report.converged = true;
      break;
    }
  }
  return report;
}

}  // namespace incise::physics
