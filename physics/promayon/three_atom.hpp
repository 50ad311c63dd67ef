// The seed's 3-atom stability test in 3-D (seed 002 §1.3 Fig. 10, §5.2), shared by the test
// (tests/unit/test_shape_memory.cpp, which checks it against the linear analysis) and `incise
// bench stability`'s summary: the volumetric model needs a triplet, so the perturbed atom A sits
// at the apex of a regular tetrahedron (unit edges) over three fixed atoms B, C, D (the seed's B
// and C plus one). Mass-spring: a spring k_r and a dashpot k_a on each of A's edges (the
// network's damping is per spring, §1.2's D); shape memory: k_e on A and the per-atom damping
// -k_a v of the seed's step. Stiffnesses matched by the trace of A's 3 x 3 stiffness
// (3 k_r = 3 k_e: k_r = k_e). Unit masses; explicit Euler.
#pragma once

#include "physics/promayon/shape_memory.hpp"
#include "physics/promayon/spring_network.hpp"

#include <cstdint>
#include <functional>
#include <vector>

namespace incise::physics {

struct ThreeAtom {
  Vector rest = Vector(12);  // A, then B, C, D
  std::vector<std::vector<int>> neighbours{{1, 2, 3}, {0, 2, 3}, {0, 1, 3}, {0, 1, 2}};
  std::vector<std::uint8_t> fixed{0, 1, 1, 1};
  ThreeAtom();
  ShapeMemory shape_memory(double stiffness) const;
  // A's springs only (the fixed atoms' springs among themselves do not act on A).
  SpringNetwork mass_spring(double stiffness, double dashpot) const;
};

// Stable: after 4000 explicit Euler steps of the seed's step (damping k_a per atom) from A moved
// by about 4e-6, A's perturbation has not grown (and never exceeded 1e-4).
bool three_atom_stable(DeformableModel& model, const ThreeAtom& t, double damping, double dt);

// The largest dt in [1e-3, 10] for which is_stable holds, by bisection to 1e-4 relative.
double largest_stable_dt(const std::function<bool(double)>& is_stable);

struct ThreeAtomLimits {
  double shape_memory = 0, mass_spring = 0;  // largest stable dt, in units of sqrt(m / k)
};
// The seed's figure: both limits at k = 0.05 and k_a = 1 (unit masses; the seed's ratio is 2).
ThreeAtomLimits three_atom_limits(double stiffness = 0.05, double damping = 1);

}  // namespace incise::physics
