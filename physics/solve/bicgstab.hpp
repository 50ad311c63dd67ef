// Preconditioned BiCGSTAB (van der Vorst 1992) for the non-symmetric systems the CG cannot take
// (an implicit step whose model has a non-symmetric stiffness: the mass-spring's correction
// forces), with the fixed degrees of freedom projected out as the filtered CG does
// (physics/core/cg.hpp): the same settings, budget and result.
#pragma once

#include "physics/core/cg.hpp"

#include <cstdint>
#include <vector>

namespace incise::physics {

// Solves A x = b on the free degrees of freedom, A non-singular there (symmetry not needed).
// - `x` is the initial guess on entry (scaled to the multiple of it with the least residual)
//   and the solution on exit; fixed entries are zero.
// - `precondition` approximates A^-1 (any fixed operator; its output is zeroed on fixed nodes).
// - result.iterations counts BiCGSTAB iterations, two products of A each; the tolerance is on
//   |r| / |b| over the free dofs, as the CG's. A breakdown (r0.v or t.t vanishing) ends the
//   solve unconverged with the last iterate.
// Deterministic: the same inputs give bitwise the same x.
CgResult bicgstab(const LinearOperator& apply, const Vector& b, const Preconditioner& precondition,
                  const std::vector<uint8_t>& fixed_nodes, Vector& x, const CgSettings& settings = {});

}  // namespace incise::physics
