// A multiplicative two-grid V-cycle preconditioner for a symmetric positive definite system B
// (issue 29): the fine level smoothed by a Chebyshev polynomial of the Jacobi-scaled operator
// (only B's product and its diagonal), the coarse level the warped Galerkin factor of the
// embedded trilinear grid (coarse_space.hpp, rest_factor.hpp):
//   pre-smooth  x = S r,           r1 = r - B x
//   correct     x += C r1,         C = R P (P^T A0 P)^-1 P^T R^T (warped_solve)
//   post-smooth x += S r2,         r2 = r - B x
// S = p(D^-1 B) D^-1 is symmetric, so the cycle I - M^-1 B = (I - S B)(I - C B)(I - S B) is
// self-adjoint in the B inner product and M^-1 symmetric: CG stays valid. It is positive
// definite while the smoother contracts in the B norm, which the Chebyshev interval's upper end
// (an over-estimate of the largest eigenvalue of D^-1 B) ensures.
//
// The implicit step (physics/core/implicit_euler.cpp, `multigrid`) runs this cycle on the rest
// system B = A0 in the rest frame, unwarped, its products those of the assembled A0
// (block_system.hpp), and warps the whole cycle: M^-1 = R V0 R^T. Every product is then the
// cheap block one, and the operator fixed between factor builds. It runs it as RestVcycle
// (rest_vcycle.hpp), the same operations with the passes fused; `multigrid_current` runs it on
// the current system as CurrentVcycle (current_vcycle.hpp), fused likewise, with these bits.
// The tests run this class as the reference.
//
// Unlike the additive two-level (Jacobi + C), the correction acts on the residual the
// smoother leaves, so the smoother and the coarse grid do not fight over the smooth modes.
#pragma once

#include "physics/core/cg.hpp"
#include "physics/solve/block_system.hpp"
#include "physics/solve/jacobi_scaling.hpp"
#include "physics/solve/rest_factor.hpp"

#include <Eigen/Geometry>
#include <Eigen/SparseCore>

#include <cstdint>
#include <vector>

namespace incise::physics {

// The largest eigenvalue of D^-1 A for a symmetric positive definite A (D its diagonal), by
// `steps` Lanczos iterations on D^-1/2 A D^-1/2 from a fixed start: the largest Ritz value,
// which approaches it from below (deterministic).
double largest_jacobi_eigenvalue(const Eigen::SparseMatrix<double>& a, int steps = 24);
// The same Lanczos from the same start on an assembled block system (its product on the
// calling thread): the rest factor's estimate, several times cheaper than forming the scalar
// matrix for it. Its products round differently, so the estimate agrees to round-off only.
double largest_jacobi_eigenvalue(const BlockSystem& a, int steps = 24);
// The largest eigenvalue of B^-1 A, B the 3x3 node blocks of A's diagonal (jacobi_scaling.hpp),
// by the same Lanczos on B^-1/2 A B^-1/2 (B^-1/2 each block's symmetric inverse root).
double largest_block_jacobi_eigenvalue(const BlockSystem& a, int steps = 24);

struct ChebyshevSmoother {
  int degree = 2;      // A products per smoothing (1: damped Jacobi)
  double upper = 2;    // the interval [upper / ratio, upper] whose eigenvalues of D^-1 A it damps
  double ratio = 30;   // the low end, below which the coarse grid takes over
  // D: A's 3x3 node blocks (point-block Jacobi, jacobi_scaling.hpp), else its diagonal; the
  // fused current cycle's choice (CurrentVcycle), `upper` then bounding B^-1 A's spectrum.
  bool node_blocks = false;
};

// The Chebyshev iteration's steps on D^-1 A over [upper / ratio, upper] (Saad, Iterative
// Methods, algorithm 12.1): s_0 = D^-1 r_0 / theta, then s_k = a_k s_(k-1) + b_k D^-1 r_k,
// x += s_k, r_(k+1) = r_k - A s_k. The same for every call, so pre- and post-smoothing are
// one symmetric S.
struct ChebyshevSteps {
  explicit ChebyshevSteps(const ChebyshevSmoother& smoother);
  double theta = 1;
  std::vector<double> a, b;  // a[k], b[k] for k = 1 .. degree - 1 (index 0 unused)
};

class VcyclePreconditioner {
 public:
  // `apply`: B; `scaling`: the smoother's D^-1 (jacobi_inverse's vector, or node blocks);
  // `coarse`: a coarse RestFactor; `rotations`: its warp (empty: none); `fixed`: per node,
  // 1 = fixed (zeroed throughout).
  VcyclePreconditioner(const LinearOperator& apply, JacobiScaling scaling, const RestFactor& coarse,
                       std::vector<Eigen::Quaterniond> rotations, const std::vector<std::uint8_t>& fixed,
                       ChebyshevSmoother smoother);

  // z = M^-1 r: 2 x degree products of B and a coarse solve. Not re-entrant (workspace).
  void operator()(const Vector& r, Vector& z);

 private:
  // x += S residual; residual -= A (that increment) unless `keep_residual` is false.
  void smooth(Vector& x, Vector& residual, bool keep_residual);
  void zero_fixed(Vector& v) const;

  const LinearOperator& apply_;
  JacobiScaling scaling_;
  const RestFactor& coarse_;
  std::vector<Eigen::Quaterniond> rotations_;
  const std::vector<std::uint8_t>& fixed_;
  ChebyshevSmoother smoother_;
  Vector residual_, step_, product_, correction_, scaled_;
};

}  // namespace incise::physics
