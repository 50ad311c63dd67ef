// Matrix-free preconditioned conjugate gradient with fixed degrees of freedom projected out
// (the filtered CG of Baraff & Witkin 1998, section 5.3): Jacobi, or any SPD preconditioner
// given as a function (physics/solve/warped_preconditioner.hpp).
#pragma once

#include <cstdint>
#include <functional>
#include <span>
#include <vector>

#include "physics/core/model.hpp"

namespace incise::physics {

// Real time (issue 29): a live session's step must end before the hand is a step ahead, so
// its CG stops at a wall-clock deadline however far from the tolerance, the body left short
// of equilibrium rather than behind the hand (SOFA's users cap CG's iterations for the same
// reason). A truncated CG from the previous step's dv is still the A-norm-best dv of its
// Krylov space. The stop depends on the machine's speed, so a recording keeps the iterations
// each stopped CG did, and its replay stops there (`stop_at`) to take the same steps.
struct CgBudget {
  std::int64_t deadline_ns = 0;  // CLOCK_MONOTONIC (steady_now_ns); 0: none
  int min_iterations = 1;        // done even when the deadline has already passed
  int stop_at = 0;               // > 0: a recorded stop, exactly this many iterations (the deadline is ignored)
};

// True when a CG that has done `iterations` iterations, not converged, must stop here.
bool budget_spent(const CgBudget& budget, int iterations);

// out = A p. `out` is already sized like p; the callable overwrites it.
using LinearOperator = std::function<void(const Vector& p, Vector& out)>;
// out[k] = A p[k] for every k, each bitwise the LinearOperator's product of the same A, in one
// pass over A (a matrix too large for the caches is read once for all of them). `out[k]` is
// already sized like p[k].
using SeveralOperator = std::function<void(std::span<const Vector> p, std::span<Vector> out)>;

struct CgSettings {
  double tolerance = 1e-6;  // on |r| / |b|, both restricted to the free degrees of freedom
  int max_iterations = 200;
  CgBudget budget;
  // Earlier solutions besides x's start, newest first (WarmStart::older): CG starts from the
  // best combination of x and these in A's norm, one product each (warm_start.hpp). Empty:
  // from x scaled to its best multiple. Read during the call only.
  std::span<const Vector> start_space;
  // The start's products of x and start_space in one pass (each bitwise the start's operator's:
  // `exact` where given, else `apply`); empty: one product each.
  SeveralOperator start_products;
};

struct CgResult {
  int iterations = 0;
  int exact_checks = 0;  // residuals taken on the exact operator (preconditioned_conjugate_gradient's `exact`)
  double relative_residual = 0;
  bool converged = false;
  bool nonfinite = false;  // a NaN or infinity appeared; x holds the last finite iterate
  bool non_positive_curvature = false;  // p.Ap <= 0: the operator is not positive definite
  bool stopped_by_budget = false;  // not converged: the deadline passed or a recorded stop was reached
};


// z = P^-1 r for an SPD P. `out` is already sized like r; the callable overwrites it.
using Preconditioner = std::function<void(const Vector& r, Vector& out)>;

// Solves A x = b on the free degrees of freedom, A symmetric positive definite there.
// - `x` is the initial guess on entry (its size must match b) and the solution on exit. CG
//   starts from its best multiple, or from the best combination of it and
//   settings.start_space (physics/core/warm_start.hpp's Galerkin start).
// - `fixed_nodes` holds one entry per node (3 degrees of freedom each), 1 = fixed; empty means
//   nothing fixed. Fixed entries of x are set to zero and the residual and search directions
//   are kept zero there, so the solution lies in the free subspace.
// - `diagonal` is the diagonal of A for the Jacobi preconditioner; entries that are not
//   positive and finite fall back to 1.
// Deterministic: the same inputs give bitwise the same x.
CgResult conjugate_gradient(const LinearOperator& apply, const Vector& b, const Vector& diagonal,
                            const std::vector<uint8_t>& fixed_nodes, Vector& x,
                            const CgSettings& settings = {});

// 1 / diagonal, entry by entry, with 1 where an entry is not positive and finite: the Jacobi
// preconditioner of conjugate_gradient above (and the fine part of a two-level one).
Vector jacobi_inverse(const Vector& diagonal);

// The same with the preconditioner `precondition` (its output is zeroed on fixed nodes).
// `exact` (optional): the system itself, `apply` then a cheaper approximation of it (the
// assembled product on K's blocks rounded to float, half the bytes). CG iterates on `apply`;
// when its residual reaches the tolerance, the residual of `exact` decides: below it, CG has
// converged (the result reports that residual); above it, CG goes on from it, restarted
// (iterative refinement in the Krylov space: each round reduces the exact residual while
// `apply` is within a factor of `exact`), so a converged result always meets the tolerance on
// the system itself.
CgResult preconditioned_conjugate_gradient(const LinearOperator& apply, const Vector& b, const Preconditioner& precondition,
                            const std::vector<uint8_t>& fixed_nodes, Vector& x, const CgSettings& settings = {},
                            const LinearOperator* exact = nullptr);

// What the Krylov solvers share (this CG, solve/bicgstab.cpp). zero_fixed_nodes: v's entries of
// the fixed nodes set to 0. start_krylov: checks the sizes (`who` names the solver in the
// message), zeroes the fixed entries of the guess x (a non-finite guess, which carries no
// information, becomes 0) and returns b with them zeroed in `filtered_b` and its norm in
// `b_norm`; false with `result` final when b is non-finite (result.nonfinite) or zero (x = 0,
// converged): the solver returns it as it is.
void zero_fixed_nodes(const std::vector<uint8_t>& fixed_nodes, Vector& v);
bool start_krylov(const char* who, const Vector& b, const std::vector<uint8_t>& fixed_nodes, Vector& x,
                  Vector& filtered_b, double& b_norm, CgResult& result);

}  // namespace incise::physics
