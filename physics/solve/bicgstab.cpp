#include "physics/solve/bicgstab.hpp"

#include <cmath>
#include <stdexcept>
#include <string>

namespace incise::physics {

CgResult bicgstab(const LinearOperator& apply, const Vector& b, const Preconditioner& precondition,
                  const std::vector<uint8_t>& fixed_nodes, Vector& x, const CgSettings& settings) {
  const Eigen::Index size = b.size();
  CgResult result;
  Vector filtered_b;
  double b_norm = 0;
  if (!start_krylov("bicgstab", b, fixed_nodes, x, filtered_b, b_norm, result)) return result;
  Vector v(size), residual(size);
  apply(x, v);
  zero_fixed_nodes(fixed_nodes, v);
  // The guess's multiple with the least residual, a = (A x0).b / |A x0|^2 (the CG's A-norm
  // scaling needs a symmetric A): never worse than the guess as given or a zero start.
  if (const double vv = v.squaredNorm(); vv > 0 && std::isfinite(vv)) {
    const double scale = v.dot(filtered_b) / vv;
    if (std::isfinite(scale)) x *= scale, v *= scale;
  }
  residual = filtered_b - v;
  const auto finish = [&](double norm) {
    if (!std::isfinite(norm)) return result.nonfinite = true;
    result.relative_residual = norm / b_norm;
    return result.converged = result.relative_residual <= settings.tolerance;
  };
  if (finish(residual.norm())) return result;
  const Vector shadow = residual;  // r0^, fixed
  Vector direction = Vector::Zero(size), y(size), s(size), z(size), t(size);
  v.setZero();
  double rho = 1, alpha = 1, omega = 1;
  while (result.iterations < settings.max_iterations) {
    const double rho_next = shadow.dot(residual);
    if (rho_next == 0.0 || omega == 0.0) break;  // breakdown: the last iterate stands
    const double beta = (rho_next / rho) * (alpha / omega);
    rho = rho_next;
    direction = residual + beta * (direction - omega * v);
    precondition(direction, y);
    zero_fixed_nodes(fixed_nodes, y);
    apply(y, v);
    zero_fixed_nodes(fixed_nodes, v);
    const double shadow_v = shadow.dot(v);
    if (shadow_v == 0.0 || !std::isfinite(shadow_v)) break;
    alpha = rho / shadow_v;
    s = residual - alpha * v;
    ++result.iterations;
    if (finish(s.norm())) {
      x += alpha * y;
      if (!x.allFinite()) result.nonfinite = true, result.converged = false;
      return result;
    }
    if (result.nonfinite) return result;
    precondition(s, z);
    zero_fixed_nodes(fixed_nodes, z);
    apply(z, t);
    zero_fixed_nodes(fixed_nodes, t);
    const double tt = t.squaredNorm();
    omega = tt > 0 ? t.dot(s) / tt : 0.0;
    x += alpha * y + omega * z;
    residual = s - omega * t;
    if (!x.allFinite()) {
      result.nonfinite = true;
      return result;
    }
    if (finish(residual.norm()) || result.nonfinite) return result;
    if (budget_spent(settings.budget, result.iterations)) {
      result.stopped_by_budget = true;
      return result;
    }
  }
  return result;
}

}  // namespace incise::physics
