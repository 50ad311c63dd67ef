#include "physics/core/cg.hpp"

#include "physics/core/stopwatch.hpp"
#include "physics/core/warm_start.hpp"

#include <cmath>
#include <stdexcept>
#include <string>

namespace incise::physics {

void zero_fixed_nodes(const std::vector<uint8_t>& fixed_nodes, Vector& v) {
  for (size_t node = 0; node < fixed_nodes.size(); ++node) {
    if (fixed_nodes[node] != 0) v.segment<3>(3 * static_cast<Eigen::Index>(node)).setZero();
  }
}

bool start_krylov(const char* who, const Vector& b, const std::vector<uint8_t>& fixed_nodes, Vector& x,
                  Vector& filtered_b, double& b_norm, CgResult& result) {
  const Eigen::Index size = b.size();
  if (x.size() != size) {
    throw std::invalid_argument(std::string(who) + ": x (" + std::to_string(x.size()) +
                                ") must have the size of b (" + std::to_string(size) + ")");
  }
  if (!fixed_nodes.empty() && static_cast<Eigen::Index>(3 * fixed_nodes.size()) != size) {
    throw std::invalid_argument(std::string(who) + ": fixed_nodes has " +
                                std::to_string(fixed_nodes.size()) + " nodes, b has " +
                                std::to_string(size) + " entries (3 per node expected)");
  }
  zero_fixed_nodes(fixed_nodes, x);
  if (!x.allFinite()) x.setZero();  // a non-finite guess carries no information
  filtered_b = b;
  zero_fixed_nodes(fixed_nodes, filtered_b);
  b_norm = filtered_b.norm();
  if (!std::isfinite(b_norm)) {
    result.nonfinite = true;
    return false;
  }
  if (b_norm == 0.0) {
    x.setZero();
    result.converged = true;
    return false;
  }
  return true;
}

namespace {

void zero_fixed(const std::vector<uint8_t>& fixed_nodes, Vector& v) { zero_fixed_nodes(fixed_nodes, v); }

}  // namespace

bool budget_spent(const CgBudget& budget, int iterations) {
  if (budget.stop_at > 0) return iterations >= budget.stop_at;
  return budget.deadline_ns > 0 && iterations >= budget.min_iterations && steady_now_ns() >= budget.deadline_ns;
}

Vector jacobi_inverse(const Vector& diagonal) {
  Vector inverse(diagonal.size());
  for (Eigen::Index i = 0; i < diagonal.size(); ++i) {
    const double d = diagonal[i];
    inverse[i] = (d > 0.0 && std::isfinite(d)) ? 1.0 / d : 1.0;
  }
  return inverse;
}

CgResult conjugate_gradient(const LinearOperator& apply, const Vector& b, const Vector& diagonal,
                            const std::vector<uint8_t>& fixed_nodes, Vector& x,
                            const CgSettings& settings) {
  if (diagonal.size() != b.size()) {
    throw std::invalid_argument("conjugate_gradient: diagonal (" + std::to_string(diagonal.size()) +
                                ") must have the size of b (" + std::to_string(b.size()) + ")");
  }
  const Vector inverse_diagonal = jacobi_inverse(diagonal);
  const Preconditioner jacobi = [&](const Vector& r, Vector& out) { out = inverse_diagonal.cwiseProduct(r); };
  return preconditioned_conjugate_gradient(apply, b, jacobi, fixed_nodes, x, settings);
}

namespace {

// residual = b - exact(x) on the free entries, its norm relative to |b| in the result; false
// when it is not finite (result.nonfinite).
bool take_exact_residual(const LinearOperator& exact, const Vector& b, double b_norm,
                         const std::vector<uint8_t>& fixed_nodes, const Vector& x, Vector& product, Vector& residual,
                         CgResult& result) {
  exact(x, product);
  residual = b - product;
  zero_fixed(fixed_nodes, residual);
  ++result.exact_checks;
  const double norm = residual.norm();
  if (!std::isfinite(norm)) {
    result.nonfinite = true;
    return false;
  }
  result.relative_residual = norm / b_norm;
  return true;
}

}  // namespace

CgResult preconditioned_conjugate_gradient(const LinearOperator& apply, const Vector& b, const Preconditioner& precondition,
                            const std::vector<uint8_t>& fixed_nodes, Vector& x, const CgSettings& settings,
                            const LinearOperator* exact) {
  const Eigen::Index size = b.size();
  CgResult result;
  Vector filtered_b;
  double b_norm = 0;
  if (!start_krylov("conjugate_gradient", b, fixed_nodes, x, filtered_b, b_norm, result)) return result;

  Vector product(size);
  // The start's products are the system's own where `apply` approximates it: the combination
  // rests on the small differences between the solutions, which a float product's round-off
  // blurs (an EFG beam's steps took more iterations from such a start than from the last dv).
  galerkin_start(exact ? *exact : apply, filtered_b, fixed_nodes, settings.start_space, x, product,
                 settings.start_products ? &settings.start_products : nullptr);
  Vector residual = filtered_b - product;
  zero_fixed(fixed_nodes, residual);
  double residual_norm = residual.norm();
  if (!std::isfinite(residual_norm)) {
    result.nonfinite = true;
    return result;
  }
  result.relative_residual = residual_norm / b_norm;
  // Below the tolerance on `apply`: converged, or (with `exact`) restarted from the exact
  // residual when that one is still above it.
  bool restart = false;
  auto converged = [&] {
    if (result.relative_residual > settings.tolerance) return false;
    if (exact) {
      if (!take_exact_residual(*exact, filtered_b, b_norm, fixed_nodes, x, product, residual, result)) return true;
      restart = result.relative_residual > settings.tolerance;
      if (restart) return false;
    }
    result.converged = true;
    return true;
  };
  if (converged()) return result;

  Vector preconditioned(size);
  precondition(residual, preconditioned);
  zero_fixed(fixed_nodes, preconditioned);
  Vector direction = preconditioned;
  double residual_dot_preconditioned = residual.dot(preconditioned);
  Vector candidate(size);

  while (result.iterations < settings.max_iterations) {
    apply(direction, product);
    zero_fixed(fixed_nodes, product);
    const double curvature = direction.dot(product);
    if (!std::isfinite(curvature)) {
      result.nonfinite = true;
      return result;
    }
    if (curvature <= 0.0) {
      result.non_positive_curvature = true;
      return result;
    }
    // Step length minimising the A-norm of the error along the direction.
    const double step = residual_dot_preconditioned / curvature;
    candidate = x + step * direction;
    if (!std::isfinite(step) || !candidate.allFinite()) {
      result.nonfinite = true;
      return result;
    }
    x.swap(candidate);
    residual -= step * product;
    ++result.iterations;

    residual_norm = residual.norm();
    if (!std::isfinite(residual_norm)) {
      result.nonfinite = true;
      return result;
    }
    result.relative_residual = residual_norm / b_norm;
    restart = false;
    if (converged()) return result;
    if (budget_spent(settings.budget, result.iterations)) {
      result.stopped_by_budget = true;
      return result;
    }

    precondition(residual, preconditioned);
    zero_fixed(fixed_nodes, preconditioned);
    const double next_dot = residual.dot(preconditioned);
    // Fletcher-Reeves form of beta, exact in exact arithmetic for a fixed preconditioner; a
    // restart (the exact residual replaced CG's) begins a new Krylov space.
    const double beta = restart ? 0.0 : next_dot / residual_dot_preconditioned;
    residual_dot_preconditioned = next_dot;
    if (restart)
      direction = preconditioned;
    else
      direction = preconditioned + beta * direction;
  }
  return result;
}

}  // namespace incise::physics
