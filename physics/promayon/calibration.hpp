// Stiffness from Young's modulus for Promayon's models (seed 002 §1.10, §8.3): the seed
// identifies k_e with E through analytic tests (plate deflection: E linear in k_e; cantilever:
// k_e "can be assimilated to a Young's modulus") but prints no constant. Here the constant is a
// calibration run: a block of 4 x 4 x 4 cells of side h, clamped between two plates (bottom
// atoms fixed, top atoms moved down by 0.1 % of the height and fixed), relaxed to equilibrium
// by the seed's explicit step with damping, the plates' force measured:
//   E_apparent = F / (A strain),  A = (4 h)^2,
// for unit stiffness and h = 1. The models are linear in their stiffness and the lattice scales
// with h, so E = C k / h, C the run's result, and a body of spacing h takes k = E h / C.
//
// What this does not capture (measured in tests/unit/test_shape_memory.cpp): the shape
// memory's stiffness against a homogeneous strain comes from the boundary atoms only (an
// interior atom's neighbourhood is centrally symmetric, and a triplet's normal term and its
// mirror image's cancel under any affine map), so the apparent modulus of a larger block at the
// same k_e is lower; nu has no counterpart in
// either model (the VN1 network's Poisson ratio is 0) and is not used.
#pragma once

#include "physics/promayon/lattice.hpp"
#include "physics/promayon/shape_memory.hpp"

namespace incise::physics {

enum class PromayonKind { shape_memory, spring_network };

// C: the apparent modulus of the calibration block at unit stiffness and spacing, Pa m / (N/m).
// Computed once per (kind, neighbourhood) and cached (thread-safe).
// `selection`: the shape memory's triplets (ignored by the network).
double calibration_constant(PromayonKind kind, Neighbourhood neighbourhood,
                            TripletSelection selection = TripletSelection::all);

// The calibration run itself on a block of `cells`^3 cells (the constant uses 4): the apparent
// modulus at unit stiffness and spacing. Throws std::runtime_error if it does not settle.
double apparent_modulus(PromayonKind kind, Neighbourhood neighbourhood, int cells,
                        TripletSelection selection = TripletSelection::all);

// The stiffness (k_e or k_r, N/m) that gives a body of lattice spacing h the modulus E.
double stiffness_from_youngs_modulus(PromayonKind kind, Neighbourhood neighbourhood, double youngs_modulus,
                                     double spacing, TripletSelection selection = TripletSelection::all);

}  // namespace incise::physics
