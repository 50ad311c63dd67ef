#include "physics/core/warm_start.hpp"

#include <Eigen/Eigenvalues>

#include <cmath>

namespace incise::physics {

namespace {

// G's eigenvalues under this fraction of its largest are left out: solutions parallel to
// round-off. Consecutive solutions differ by a small part of themselves, and that difference,
// the direction the motion is heading, sits in eigenvalues of 1e-6 relative and below: a
// floor of 1e-6 lost a third of the iterations saved (docs/status.md).
constexpr double eigenvalue_floor = 1e-10;

// The single solution: x scaled to a x, a = x.b / x.A x (the projection on x alone).
void scale(const Vector& b, Vector& x, Vector& product) {
  const double curvature = x.dot(product);
  if (!(curvature > 0.0) || !std::isfinite(curvature)) return;
  const double a = x.dot(b) / curvature;
  if (!std::isfinite(a) || a == 1.0) return;
  x *= a;
  product *= a;
}

}  // namespace

Vector WarmStart::newest(Eigen::Index size) const {
  if (solutions_.empty() || solutions_.front().size() != size) return Vector::Zero(size);
  return solutions_.front();
}

std::span<const Vector> WarmStart::older(Eigen::Index size) const {
  if (solutions_.size() < 2 || solutions_.front().size() != size) return {};
  return std::span<const Vector>(solutions_).subspan(1);
}

void WarmStart::record(const Vector& solution) {
  if (!solutions_.empty() && solutions_.front().size() != solution.size()) solutions_.clear();
  if (static_cast<int>(solutions_.size()) == depth_) solutions_.pop_back();
  solutions_.insert(solutions_.begin(), solution);
}

void WarmStart::zero_node(int node) {
  for (Vector& solution : solutions_)
    if (3 * static_cast<Eigen::Index>(node) + 3 <= solution.size()) solution.segment<3>(3 * static_cast<Eigen::Index>(node)).setZero();
}

void galerkin_start(const LinearOperator& apply, const Vector& b,
                    const std::vector<std::uint8_t>& fixed_nodes, std::span<const Vector> older, Vector& x,
                    Vector& product, const SeveralOperator* several) {
  if (older.empty()) {
    apply(x, product);
    zero_fixed_nodes(fixed_nodes, product);
    scale(b, x, product);
    return;
  }
  // The directions: x, then the older solutions (their fixed entries zeroed, as x's are).
  const int count = 1 + static_cast<int>(older.size());
  std::vector<Vector> directions(static_cast<size_t>(count)), products(static_cast<size_t>(count));
  directions[0] = x;
  for (int i = 1; i < count; ++i) {
    directions[static_cast<size_t>(i)] = older[static_cast<size_t>(i - 1)];
    zero_fixed_nodes(fixed_nodes, directions[static_cast<size_t>(i)]);
  }
  for (Vector& p : products) p.resize(b.size());
  if (several) {
    (*several)(directions, products);
  } else {
    for (int i = 0; i < count; ++i) apply(directions[static_cast<size_t>(i)], products[static_cast<size_t>(i)]);
  }
  for (Vector& p : products) zero_fixed_nodes(fixed_nodes, p);
  product = products[0];
  Eigen::MatrixXd gram(count, count);
  Eigen::VectorXd projection(count);
  for (int i = 0; i < count; ++i) {
    projection[i] = directions[static_cast<size_t>(i)].dot(b);
    for (int j = 0; j <= i; ++j)
      gram(i, j) = gram(j, i) = 0.5 * (directions[static_cast<size_t>(i)].dot(products[static_cast<size_t>(j)]) +
                                       directions[static_cast<size_t>(j)].dot(products[static_cast<size_t>(i)]));
  }
  // c = G^+ g over G's well-determined positive eigenvalues.
  const Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> eigen(gram);
  if (eigen.info() != Eigen::Success) return scale(b, x, product);
  const double largest = eigen.eigenvalues().maxCoeff();
  if (!(largest > 0) || !std::isfinite(largest)) return scale(b, x, product);
  const Eigen::VectorXd along = eigen.eigenvectors().transpose() * projection;
  Eigen::VectorXd scaled = Eigen::VectorXd::Zero(count);
  for (int k = 0; k < count; ++k) {
    const double value = eigen.eigenvalues()[k];
    if (value > eigenvalue_floor * largest) scaled[k] = along[k] / value;
  }
  const Eigen::VectorXd coefficients = eigen.eigenvectors() * scaled;
  if (!coefficients.allFinite()) return scale(b, x, product);
  x.setZero();
  product.setZero();
  for (int i = 0; i < count; ++i) {
    x += coefficients[i] * directions[static_cast<size_t>(i)];
    product += coefficients[i] * products[static_cast<size_t>(i)];
  }
}

}  // namespace incise::physics
