#include "physics/promayon/three_atom.hpp"

#include "physics/promayon/seed_step.hpp"

#include <cmath>

namespace incise::physics {

ThreeAtom::ThreeAtom() {
  const double s = 1 / std::sqrt(3.0), h = std::sqrt(2.0 / 3);
  rest << 0, 0, h, s, 0, 0, -s / 2, 0.5, 0, -s / 2, -0.5, 0;  // unit edges
}

ShapeMemory ThreeAtom::shape_memory(double stiffness) const {
  return ShapeMemory(rest, neighbours, Vector::Ones(4), stiffness, 1);
}

SpringNetwork ThreeAtom::mass_spring(double stiffness, double dashpot) const {
  return SpringNetwork(rest, {{1, 2, 3}, {0}, {0}, {0}}, Vector::Ones(4), stiffness, dashpot, 1);
}

bool three_atom_stable(DeformableModel& model, const ThreeAtom& t, double damping, double dt) {
  State state{t.rest, Vector::Zero(12)};
  state.positions.segment<3>(0) += Vec3(1e-6, -2e-6, 3e-6);
  const SeedStepSettings settings{dt, damping, 0, SeedScheme::explicit_euler};
  const Vector zero = Vector::Zero(12);
  for (int k = 0; k < 4000; ++k) {
    if (seed_explicit_step(model, state, t.fixed, zero, {}, settings, nullptr, 0).nonfinite) return false;
    if ((state.positions - t.rest).norm() > 1e-4) return false;
  }
  return (state.positions - t.rest).norm() < 4e-6;
}

double largest_stable_dt(const std::function<bool(double)>& is_stable) {
  double lo = 1e-3, hi = 10;
  while (hi - lo > 1e-4 * lo) {
    const double mid = 0.5 * (lo + hi);
    (is_stable(mid) ? lo : hi) = mid;
  }
  return lo;
}

ThreeAtomLimits three_atom_limits(double stiffness, double damping) {
  const ThreeAtom t;
  ShapeMemory sm = t.shape_memory(stiffness);
  SpringNetwork ms = t.mass_spring(stiffness, damping);
  return {largest_stable_dt([&](double dt) { return three_atom_stable(sm, t, damping, dt); }),
          largest_stable_dt([&](double dt) { return three_atom_stable(ms, t, 0, dt); })};
}

}  // namespace incise::physics
