#include "physics/solve/rest_factor.hpp"

#include "physics/solve/galerkin.hpp"
#include "physics/solve/multigrid.hpp"
#include "physics/solve/supernodal_factor.hpp"

#include <dlfcn.h>

#include <chrono>
#include <mutex>
#include <stdexcept>

extern "C" void openblas_set_num_threads(int);

namespace incise::physics {

using SparseMatrix = Eigen::SparseMatrix<double>;

FactorBackend default_factor_backend() {
#if defined(__SANITIZE_THREAD__)
  return FactorBackend::simplicial;
#else
  return FactorBackend::cholmod;
#endif
}

namespace {

// The factor is built beside the step, whose threads have the cores: one BLAS thread, and no
// OpenMP team for CHOLMOD's supernodal loops, whose num_threads(4) clause only the number of
// active levels overrides (0: every parallel region runs on its caller alone). libgomp comes
// in with CHOLMOD, not with incise, hence the look-up; nothing else in the process uses it.
void single_threaded_factor() {
  openblas_set_num_threads(1);
  if (auto set_levels = reinterpret_cast<void (*)(int)>(dlsym(RTLD_DEFAULT, "omp_set_max_active_levels")))
    set_levels(0);
}

}  // namespace

void use_single_threaded_blas() {
  static std::once_flag once;
  std::call_once(once, single_threaded_factor);
}

// The factor is read out of its builder into a SupernodalFactor, whose solve every later call
// uses (supernodal_factor.hpp), in float for a coarse correction; the builder's copy goes.
struct RestFactor::Solver {
  SupernodalFactor factor;
  SupernodalFactor::Workspace work;
};


RestFactor::RestFactor(const BlockMatrix& stiffness, const Eigen::VectorXd& masses, const std::vector<std::uint8_t>& fixed,
                       double mass_coefficient, double stiffness_coefficient, FactorBackend backend,
                       const CoarseSpace* coarse, int smoothing_degree, bool single_precision_smoother,
                       bool node_block_smoother)
    : solver_(std::make_unique<Solver>()), size_(3 * stiffness.nodes()), backend_(backend) {
  const auto start = std::chrono::steady_clock::now();
  if (!(mass_coefficient > 0) || !(stiffness_coefficient >= 0))
    throw std::invalid_argument("RestFactor: the mass coefficient must be positive and the stiffness one non-negative");
  if (smoothing_degree > 0) {
    if (!coarse) throw std::invalid_argument("RestFactor: a V-cycle's smoother needs a coarse space");
    smoothing_degree_ = smoothing_degree;
    // The smoother's operator, in double for the estimate of its interval's upper end, then
    // rounded if asked.
    rest_system_ = BlockSystem(stiffness, masses, fixed, mass_coefficient, stiffness_coefficient);
    if (node_block_smoother) {
      // The current cycle's factor: it smooths with the step's own system, so A0 serves the
      // estimate alone and goes (the scalar estimate was a quarter of a build, its 24
      // products streaming A0 beside the steps).
      node_block_eigenvalue_ = largest_block_jacobi_eigenvalue(rest_system_);
      rest_system_ = BlockSystem();
    } else {
      smoothing_eigenvalue_ = largest_jacobi_eigenvalue(rest_system_);
      if (single_precision_smoother) rest_system_.round_to_single();
      rest_inverse_diagonal_ = rest_system_.diagonal().cwiseInverse();
      if (single_precision_smoother) rest_inverse_diagonal_ = rest_inverse_diagonal_.cast<float>().cast<double>();
      rest_fixed_ = fixed;
    }
  }
  // A coarse factor's matrix straight from the blocks (its lower triangle, what both backends
  // read); the whole system's in scalar form.
  SparseMatrix matrix;
  if (coarse) {
    prolongation_ = coarse->prolongation;
    transfer_ = CoarseTransfer(prolongation_);
    matrix = galerkin_lower(stiffness, masses, fixed, mass_coefficient, stiffness_coefficient, *coarse);
  } else {
    matrix = stiffness.system(masses, fixed, mass_coefficient, stiffness_coefficient);
  }
  if (backend == FactorBackend::cholmod) {
    use_single_threaded_blas();
    solver_->factor = SupernodalFactor::with_cholmod(matrix, coarse != nullptr);
  } else {
    solver_->factor = SupernodalFactor::with_simplicial(matrix, coarse != nullptr);
  }
  factor_nonzeros_ = solver_->factor.factor_nonzeros();
  build_ms_ = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count();
}

RestFactor::~RestFactor() = default;

void RestFactor::solve(Eigen::VectorXd& x) const {
  Eigen::VectorXd solution = coarse() ? Eigen::VectorXd(prolongation_.transpose() * x) : x;
  solve_factored(solution);
  if (coarse())
    x = prolongation_ * solution;
  else
    x.swap(solution);
}

void RestFactor::solve_factored(Eigen::VectorXd& u, Executor& executor) const {
  if (u.size() != factored_size()) throw std::invalid_argument("RestFactor::solve_factored: the vector's size is not the factor's");
  const std::lock_guard<std::mutex> lock(solving_);
  solver_->factor.solve(u.data(), solver_->work, executor);
}

}  // namespace incise::physics
