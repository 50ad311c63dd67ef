// The Cholesky factor of a body's implicit system in its rest shape,
//   A0 = mass_coefficient M + stiffness_coefficient K0   (K0: every rotation the identity),
// the fixed nodes decoupled; or, given a coarse space P (coarse_space.hpp), of its Galerkin
// coarse system P^T A0 P, whose solve is then the coarse correction P (P^T A0 P)^-1 P^T of a
// two-level preconditioner. Warped by the current rotations it preconditions the corotated
// system (physics/solve/warped_preconditioner.hpp; SOFA's WarpPreconditioner, Courtecuisse
// et al. 2010). Built by CHOLMOD (or Eigen's simplicial LLT), solved by SupernodalFactor
// (supernodal_factor.hpp; a coarse factor in float). Immutable once built, so one factor may be
// shared by the steps that use it while the next is built on another thread.
#pragma once

#include "physics/core/executor.hpp"
#include "physics/solve/block_matrix.hpp"
#include "physics/solve/block_system.hpp"
#include "physics/solve/coarse_space.hpp"
#include "physics/solve/coarse_transfer.hpp"

#include <cstdint>
#include <memory>
#include <mutex>
#include <string>
#include <vector>

namespace incise::physics {

enum class FactorBackend {
  // CHOLMOD's supernodal factorisation (dense BLAS on supernodes): several times faster to
  // build. It runs on one thread, beside the step's: OpenBLAS is limited to one, and so are
  // CHOLMOD's own OpenMP loops (they only copy and scatter, so the bits are the same either
  // way; a team of threads would wake and spin on the cores the step needs).
  cholmod,
  // Eigen's simplicial LLT (AMD ordering): no BLAS, no threads; used under ThreadSanitizer,
  // which cannot see OpenMP's and OpenBLAS's synchronisation.
  simplicial,
};

// CHOLMOD unless the build is ThreadSanitizer's.
FactorBackend default_factor_backend();

// Limits OpenBLAS to one thread and CHOLMOD's OpenMP loops to their caller for the rest of the
// process (the first call; later ones do nothing). A CHOLMOD factor's build calls it; a program
// whose other CHOLMOD solves must give the same bits before and after the first build calls it
// first (BLAS's sums depend on its thread count).
void use_single_threaded_blas();

class RestFactor {
 public:
  // `smoothing_degree` > 0 (with a coarse space): the factor is the coarse level of a V-cycle
  // (multigrid.hpp) whose Chebyshev smoother has that degree; the largest eigenvalue of
  // D0^-1 A0 that bounds its interval is estimated here, off the step's critical path.
  // `single_precision_smoother`: the smoother's copy of A0 (and D0^-1) rounded to float
  // (block_system.hpp); the factor and the estimate stay double. `node_block_smoother`: the
  // top of B0^-1 A0 (B0 A0's 3x3 node blocks) is estimated instead, for the current system's
  // cycle, which scales by the node blocks (jacobi_scaling.hpp) and smooths with the step's
  // own system: such a factor keeps no copy of A0 and serves no rest cycle.
  // Throws std::runtime_error if A0 is not positive definite (a body with a free rigid mode
  // and no mass term cannot be: the mass coefficient must be positive).
  RestFactor(const BlockMatrix& stiffness, const Eigen::VectorXd& masses, const std::vector<std::uint8_t>& fixed,
             double mass_coefficient, double stiffness_coefficient, FactorBackend backend = default_factor_backend(),
             const CoarseSpace* coarse = nullptr, int smoothing_degree = 0, bool single_precision_smoother = false,
             bool node_block_smoother = false);
  ~RestFactor();
  RestFactor(const RestFactor&) = delete;
  RestFactor& operator=(const RestFactor&) = delete;

  // x <- A0^-1 x, or P (P^T A0 P)^-1 P^T x with a coarse space (3n). A copied World shares its
  // factors with the original, so calls are serialised (the solvers keep workspace).
  void solve(Eigen::VectorXd& x) const;
  // u <- (the factored matrix)^-1 u (factored_size()): with a coarse space, the coarse solve
  // alone, between transfers the caller does itself (transfer()); on `executor`'s threads
  // (supernodal_factor.hpp: the same bits on any).
  void solve_factored(Eigen::VectorXd& u, Executor& executor = serial_executor()) const;
  bool coarse() const { return prolongation_.size() > 0; }
  // P as row-wise gathers (empty without a coarse space).
  const CoarseTransfer& transfer() const { return transfer_; }
  int factored_size() const { return coarse() ? static_cast<int>(prolongation_.cols()) : size_; }

  int size() const { return size_; }
  int smoothing_degree() const { return smoothing_degree_; }        // 0: additive two-level
  double smoothing_eigenvalue() const { return smoothing_eigenvalue_; }  // of D0^-1 A0; 0: not estimated
  double node_block_eigenvalue() const { return node_block_eigenvalue_; }  // of B0^-1 A0; 0: not estimated
  // Whether the rest cycle (rest_vcycle.hpp) or the two-level may use it: not a current-cycle
  // factor's (node_block_smoother).
  bool serves_rest_cycles() const { return smoothing_degree_ == 0 || smoothing_eigenvalue_ > 0; }
  long long factor_nonzeros() const { return factor_nonzeros_; }
  double build_ms() const { return build_ms_; }  // the matrix and its factorisation
  // A V-cycle's factor (smoothing_degree() > 0) also keeps the rest system A0 itself in
  // blocks, its smoother's operator: y = A0 x (on `executor`'s threads), D0^-1 and the nodes
  // it fixed (empty: none). Empty for other factors.
  void rest_product(const Eigen::VectorXd& x, Eigen::VectorXd& y, Executor& executor) const {
    rest_system_.multiply(x, y, executor);
  }
  const BlockSystem& rest_system() const { return rest_system_; }
  const Eigen::VectorXd& rest_inverse_diagonal() const { return rest_inverse_diagonal_; }
  const std::vector<std::uint8_t>& rest_fixed() const { return rest_fixed_; }
  FactorBackend backend() const { return backend_; }

 private:
  struct Solver;
  std::unique_ptr<Solver> solver_;
  mutable std::mutex solving_;
  Eigen::SparseMatrix<double> prolongation_;  // empty: the whole system is factored
  CoarseTransfer transfer_;
  BlockSystem rest_system_;
  Eigen::VectorXd rest_inverse_diagonal_;
  std::vector<std::uint8_t> rest_fixed_;
  int size_ = 0;
  long long factor_nonzeros_ = 0;
  double build_ms_ = 0;
  int smoothing_degree_ = 0;
  double smoothing_eigenvalue_ = 0;
  double node_block_eigenvalue_ = 0;
  FactorBackend backend_;
};


}  // namespace incise::physics
