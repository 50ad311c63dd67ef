#include "physics/efg/mls.hpp"

#include "physics/efg/kernel.hpp"

#include <Eigen/Eigenvalues>

#include <array>
#include <cmath>
#include <vector>

namespace incise::physics {

namespace {
using Vec4 = Eigen::Vector4d;
using Mat4 = Eigen::Matrix4d;
}  // namespace

bool mls_shape_functions(const Vec3& point, std::span<const Vec3> particles, double support,
                         double scale, std::span<double> values, std::span<Vec3> gradients) {
  const size_t count = particles.size();
  if (values.size() != count || (!gradients.empty() && gradients.size() != count)) return false;
  if (count < 4 || !(support > 0) || !(scale > 0)) return false;

  // Eq. 4.5: A = sum_i w_i p_i p_i^T, and its derivatives A_,k = sum_i w_i,k p_i p_i^T (A.18),
  // these only when the gradients are asked for. Scratch kept per thread: a surface remapping
  // calls this for every vertex it maps.
  thread_local std::vector<Vec4> basis;
  thread_local std::vector<double> weights;
  thread_local std::vector<Vec3> weight_gradients;
  const bool with_gradients = !gradients.empty();
  basis.resize(count);
  weights.resize(count);
  weight_gradients.resize(with_gradients ? count : 0);
  Mat4 moment = Mat4::Zero();
  std::array<Mat4, 3> moment_derivative{Mat4::Zero(), Mat4::Zero(), Mat4::Zero()};
  for (size_t i = 0; i < count; ++i) {
    const Vec3 offset = particles[i] - point;
    const double distance = offset.norm();
    basis[i] << 1.0, offset / scale;
    weights[i] = quartic_spline(distance, support);
    const Mat4 outer = basis[i] * basis[i].transpose();
    moment += weights[i] * outer;
    if (!with_gradients) continue;
    // grad_x w(|x - x_i|) = w'(r) (x - x_i) / r; w'(0) = 0 removes the 0/0.
    weight_gradients[i] = distance > 0.0
                              ? Vec3(quartic_spline_derivative(distance, support) * -offset / distance)
                              : Vec3::Zero();
    for (int k = 0; k < 3; ++k) moment_derivative[k] += weight_gradients[i][k] * outer;
  }

  // The weights carry 1/h^3; normalising by the largest eigenvalue makes the test scale-free.
  const Eigen::SelfAdjointEigenSolver<Mat4> eigen(moment, Eigen::EigenvaluesOnly);
  const Vec4 eigenvalues = eigen.eigenvalues();
  if (!(eigenvalues[3] > 0) || !(eigenvalues[0] > 1e-12 * eigenvalues[3])) return false;
  const Mat4 inverse = moment.inverse();

  // Eq. 4.3 at y = point, where p(point) = e0: phi_i = e0^T A^-1 p_i w_i = w_i gamma . p_i.
  const Vec4 gamma = inverse.col(0);
  std::array<Vec4, 3> moment_gamma;
  for (int k = 0; k < 3; ++k) moment_gamma[k] = moment_derivative[k] * gamma;
  for (size_t i = 0; i < count; ++i) {
    const double projection = gamma.dot(basis[i]);
    values[i] = weights[i] * projection;
    if (!with_gradients) continue;
    // A.21 with p_,k = e_(k+1) / scale and (A^-1)_,k = -A^-1 A_,k A^-1 (A.19):
    //   phi_i,k = w_i [ (A^-1 p_i)_(k+1) / scale - (A_,k gamma) . (A^-1 p_i) ] + w_i,k gamma . p_i
    const Vec4 solved = inverse * basis[i];
    for (int k = 0; k < 3; ++k) {
      gradients[i][k] = weights[i] * (solved[k + 1] / scale - moment_gamma[k].dot(solved)) +
                        weight_gradients[i][k] * projection;
    }
  }
  return true;
}

bool spans_three_dimensions(std::span<const Vec3> points, double relative_tolerance) {
  if (points.size() < 4) return false;
  Vec3 centroid = Vec3::Zero();
  for (const Vec3& p : points) centroid += p;
  centroid /= static_cast<double>(points.size());
  Mat3 covariance = Mat3::Zero();
  for (const Vec3& p : points) covariance += (p - centroid) * (p - centroid).transpose();
  const Eigen::SelfAdjointEigenSolver<Mat3> eigen(covariance, Eigen::EigenvaluesOnly);
  const Vec3 extents = eigen.eigenvalues().cwiseMax(0.0).cwiseSqrt();
  return extents[2] > 0 && extents[0] >= relative_tolerance * extents[2];
}

}  // namespace incise::physics
