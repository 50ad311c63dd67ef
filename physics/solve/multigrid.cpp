#include "physics/solve/multigrid.hpp"

#include "physics/solve/warped_preconditioner.hpp"

#include <Eigen/Eigenvalues>

#include <algorithm>
#include <cmath>
#include <functional>
#include <stdexcept>
#include <utility>

namespace incise::physics {

namespace {

using VectorMap = std::function<void(const Vector&, Vector&)>;

// Lanczos on S A S (S symmetric: D^-1/2 or B^-1/2), `scale` computing y = S x and `product`
// y = A x, on vectors of `size`.
double lanczos_largest(Eigen::Index size, const VectorMap& scale_by, const VectorMap& product, int steps) {
  if (size == 0) return 1;
  // A start with every mode in it: not an eigenvector of a regular grid's operator.
  Vector v(size);
  for (Eigen::Index i = 0; i < size; ++i) v[i] = 1 + 0.5 * std::sin(0.7 * static_cast<double>(i));
  v.normalize();
  Vector previous = Vector::Zero(size), w(size), scaled(size), product_out(size);
  std::vector<double> alphas, betas;
  double beta = 0;
  steps = static_cast<int>(std::min<Eigen::Index>(steps, size));
  for (int k = 0; k < steps; ++k) {
    scale_by(v, scaled);
    product(scaled, product_out);
    scale_by(product_out, w);
    w -= beta * previous;
    const double alpha = v.dot(w);
    w -= alpha * v;
    alphas.push_back(alpha);
    beta = w.norm();
    if (!(beta > 1e-12 * std::abs(alpha))) break;  // an invariant subspace: the Ritz values are exact
    betas.push_back(beta);
    previous.swap(v);
    v = w / beta;
  }
  const Eigen::Index m = static_cast<Eigen::Index>(alphas.size());
  Eigen::MatrixXd tridiagonal = Eigen::MatrixXd::Zero(m, m);
  for (Eigen::Index i = 0; i < m; ++i) {
    tridiagonal(i, i) = alphas[static_cast<size_t>(i)];
    if (i + 1 < m) tridiagonal(i, i + 1) = tridiagonal(i + 1, i) = betas[static_cast<size_t>(i)];
  }
  const double largest = Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd>(tridiagonal, Eigen::EigenvaluesOnly).eigenvalues().maxCoeff();
  if (!std::isfinite(largest) || !(largest > 0))
    throw std::runtime_error("largest_jacobi_eigenvalue: the matrix is not positive definite");
  return largest;
}

// x -> D^-1/2 x (1 where an entry of D is not positive).
VectorMap diagonal_scaling(const Vector& diagonal) {
  Vector scale = diagonal;
  for (Eigen::Index i = 0; i < scale.size(); ++i) scale[i] = scale[i] > 0 ? 1 / std::sqrt(scale[i]) : 1;
  return [scale = std::move(scale)](const Vector& x, Vector& y) { y = scale.cwiseProduct(x); };
}

}  // namespace

double largest_jacobi_eigenvalue(const Eigen::SparseMatrix<double>& a, int steps) {
  return lanczos_largest(a.rows(), diagonal_scaling(a.diagonal()), [&](const Vector& x, Vector& y) { y = a * x; }, steps);
}

double largest_jacobi_eigenvalue(const BlockSystem& a, int steps) {
  return lanczos_largest(3 * static_cast<Eigen::Index>(a.nodes()), diagonal_scaling(a.diagonal()),
                         [&](const Vector& x, Vector& y) { a.multiply(x, y, serial_executor()); }, steps);
}

double largest_block_jacobi_eigenvalue(const BlockSystem& a, int steps) {
  std::vector<Mat3> roots = a.diagonal_blocks();
  for (Mat3& block : roots) block = inverse_square_root(block);
  const VectorMap scale_by = [&](const Vector& x, Vector& y) {
    y.resize(x.size());
    for (size_t node = 0; node < roots.size(); ++node) {
      const Eigen::Index offset = 3 * static_cast<Eigen::Index>(node);
      y.segment<3>(offset) = roots[node] * Vec3(x.segment<3>(offset));
    }
  };
  return lanczos_largest(3 * static_cast<Eigen::Index>(a.nodes()), scale_by,
                         [&](const Vector& x, Vector& y) { a.multiply(x, y, serial_executor()); }, steps);
}

ChebyshevSteps::ChebyshevSteps(const ChebyshevSmoother& smoother)
    : a(static_cast<size_t>(std::max(smoother.degree, 1)), 0.0), b(a.size(), 0.0) {
  const double upper = smoother.upper, lower = upper / smoother.ratio;
  const double delta = (upper - lower) / 2, sigma = (upper + lower) / 2 / delta;
  theta = (upper + lower) / 2;
  double rho = 1 / sigma;
  for (size_t k = 1; k < a.size(); ++k) {
    const double next = 1 / (2 * sigma - rho);
    a[k] = next * rho;
    b[k] = 2 * next / delta;
    rho = next;
  }
}

VcyclePreconditioner::VcyclePreconditioner(const LinearOperator& apply, JacobiScaling scaling, const RestFactor& coarse,
                                           std::vector<Eigen::Quaterniond> rotations,
                                           const std::vector<std::uint8_t>& fixed, ChebyshevSmoother smoother)
    : apply_(apply),
      scaling_(std::move(scaling)),
      coarse_(coarse),
      rotations_(std::move(rotations)),
      fixed_(fixed),
      smoother_(smoother) {
  if (smoother_.degree < 1 || !(smoother_.upper > 0) || !(smoother_.ratio > 1))
    throw std::invalid_argument("VcyclePreconditioner: the smoother needs a degree >= 1, upper > 0 and ratio > 1");
  if (!coarse_.coarse()) throw std::invalid_argument("VcyclePreconditioner: the factor is not a coarse one");
}

void VcyclePreconditioner::zero_fixed(Vector& v) const {
  for (size_t node = 0; node < fixed_.size(); ++node)
    if (fixed_[node] != 0) v.segment<3>(3 * static_cast<Eigen::Index>(node)).setZero();
}

// `degree` Chebyshev steps (ChebyshevSteps) from x's current value.
void VcyclePreconditioner::smooth(Vector& x, Vector& residual, bool keep_residual) {
  const ChebyshevSteps steps(smoother_);
  scaled_.resize(residual.size());
  scaling_.apply(residual.data(), scaled_.data(), 0, residual.size());
  step_ = scaled_ / steps.theta;
  zero_fixed(step_);
  for (int k = 0; k < smoother_.degree; ++k) {
    if (k > 0) {
      scaling_.apply(residual.data(), scaled_.data(), 0, residual.size());
      step_ = steps.a[static_cast<size_t>(k)] * step_ + steps.b[static_cast<size_t>(k)] * scaled_;
      zero_fixed(step_);
    }
    x += step_;
    if (k + 1 < smoother_.degree || keep_residual) {
      apply_(step_, product_);
      zero_fixed(product_);
      residual -= product_;
    }
  }
}

void VcyclePreconditioner::operator()(const Vector& r, Vector& z) {
  residual_ = r;
  zero_fixed(residual_);
  product_.resize(r.size());
  z.setZero(r.size());
  smooth(z, residual_, true);
  warped_solve(coarse_, rotations_, residual_, correction_);
  zero_fixed(correction_);
  z += correction_;
  apply_(correction_, product_);
  zero_fixed(product_);
  residual_ -= product_;
  smooth(z, residual_, false);
}

}  // namespace incise::physics
