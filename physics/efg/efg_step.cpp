// The corotated EFG model's step (physics/efg/corotational_efg.hpp): each element's rotation
// from the MLS deformation gradient, the elastic forces, the stiffness's product and diagonal,
// and the elastic energy, whose rotations the next step's update_rotations reuses. The build
// and the cut's edits are in corotational_efg.cpp.
#include "physics/efg/corotational_efg.hpp"

#include "physics/fem/corotational_fem.hpp"

#include <algorithm>
#include <cmath>

namespace incise::physics {

namespace {

using Index = Eigen::Index;
using Quaternion = Eigen::Quaterniond;

// The rotation maximising tr(R^T F), which is the polar rotation of F when det F > 0, by the
// axis-angle updates of Mueller, Bender, Chentanez and Macklin 2016 ("A robust method to
// extract the rotational part of deformations"), warm-started with the previous rotation.
// Their step omega = g / |tr N| (N = F R^T, g = sum_i r_i x f_i the axial vector of N - N^T)
// converges linearly (by about a factor 3 per iteration at small strain); taking the Newton
// step omega = (tr(N) I - sym N)^-1 g instead, whenever that matrix is positive definite,
// converges quadratically, so a warm start needs one or two iterations. Falls back to the
// SVD polar decomposition if it has not settled.
Quaternion extract_rotation(const Mat3& f, Quaternion q) {
  if (!f.allFinite()) return q;
  for (int iteration = 0; iteration < 24; ++iteration) {
    const Mat3 r = q.toRotationMatrix();
    const Mat3 n = f * r.transpose();
    const Vec3 g(n(2, 1) - n(1, 2), n(0, 2) - n(2, 0), n(1, 0) - n(0, 1));
    const Mat3 hessian = n.trace() * Mat3::Identity() - 0.5 * (n + n.transpose());
    const Eigen::LLT<Mat3> newton(hessian);
    const Vec3 omega = newton.info() == Eigen::Success
                           ? Vec3(newton.solve(g))
                           : Vec3(g / (std::abs(n.trace()) + 1e-9));
    const double angle = omega.norm();
    if (!(angle > 0)) return q;
    q = Quaternion(Eigen::AngleAxisd(angle, omega / angle)) * q;
    q.normalize();
    if (angle < 1e-8) return q;  // the remaining error is of order angle^2
  }
  return Quaternion(CorotationalTetFem::polar_rotation(f)).normalized();
}

// Linear strain and Hooke stress of a displacement gradient.
struct StrainStress {
  Mat3 strain;
  Mat3 stress;
};

StrainStress hooke(const Mat3& displacement_gradient, double lambda, double mu) {
  const Mat3 strain = 0.5 * (displacement_gradient + displacement_gradient.transpose());
  return {strain, 2.0 * mu * strain + lambda * strain.trace() * Mat3::Identity()};
}

}  // namespace

Quaternion CorotationalEfg::element_rotation(const Vector& x, int element,
                                             const Quaternion& start) const {
  const size_t base = static_cast<size_t>(element) * stride_;
  const std::vector<Vec3>& coefficients = shape_->settings.rotation == EfgRotation::shape_matching
                                              ? matching_coefficients_
                                              : shape_gradients_;
  Mat3 fit = Mat3::Zero();
  for (int k = 0; k < row_lengths_[element]; ++k) {
    fit += x.segment<3>(3 * static_cast<Index>(neighbours_[base + k])) *
           coefficients[base + k].transpose();
  }
  return extract_rotation(fit, start);
}

void CorotationalEfg::update_rotations(const Vector& x) {
  // elastic_energy already extracted the rotations at these very positions from these warm
  // starts (the previous step's end): the same computation, so its results are taken as they
  // are. Bitwise equal positions only: any other x is extracted afresh.
  const bool cached = energy_positions_.size() == x.size() && x.size() > 0 &&
                      std::memcmp(energy_positions_.data(), x.data(), sizeof(double) * static_cast<size_t>(x.size())) == 0 &&
                      energy_valid_.size() == static_cast<size_t>(element_count());
  executor_->parallel_for(element_count(), [&](int begin, int end) {
    for (int e = begin; e < end; ++e) {
      orientations_[e] = cached && energy_valid_[e] ? energy_orientations_[e] : element_rotation(x, e, orientations_[e]);
      rotations_[e] = orientations_[e].toRotationMatrix();
    }
  }, std::max(1, shape_->settings.threaded_elements / 2));
  // The warm starts moved on: the kept rotations no longer repeat an extraction from them.
  energy_positions_.resize(0);
}

template <typename ElementTerm>
void CorotationalEfg::accumulate(Vector& out, const ElementTerm& term) const {
  const int elements = element_count();
  const Index size = 3 * static_cast<Index>(node_count());
  // Fixed partitions of the elements, each scattering into its own buffer in element order;
  // the buffers are then added in partition order. Neither depends on the thread count.
  executor_->parallel_for(partition_count, [&](int begin, int end) {
    for (int part = begin; part < end; ++part) {
      Vector& buffer = partition_buffers_[part];
      if (buffer.size() != size) buffer.resize(size);
      buffer.setZero();
      const int first = static_cast<int>(static_cast<long long>(elements) * part / partition_count);
      const int last = static_cast<int>(static_cast<long long>(elements) * (part + 1) / partition_count);
      for (int e = first; e < last; ++e) term(e, buffer);
    }
  }, elements >= shape_->settings.threaded_elements ? 1 : partition_count);
  executor_->parallel_for(node_count(), [&](int begin, int end) {
    for (Index i = 3 * static_cast<Index>(begin); i < 3 * static_cast<Index>(end); ++i) {
      double sum = partition_buffers_[0][i];
      for (int part = 1; part < partition_count; ++part) sum += partition_buffers_[part][i];
      out[i] += sum;
    }
  }, std::max(1, shape_->settings.threaded_elements / 4));
}

void CorotationalEfg::add_elastic_forces(const Vector& x, Vector& f) const {
  accumulate(f, [&](int e, Vector& buffer) {
    const size_t base = static_cast<size_t>(e) * stride_;
    const int length = row_lengths_[e];
    Mat3 gradient = Mat3::Zero();
    for (int k = 0; k < length; ++k) {
      gradient.noalias() += x.segment<3>(3 * static_cast<Index>(neighbours_[base + k])) *
                            shape_gradients_[base + k].transpose();
    }
    // grad u = sum_n (R^T x_n - X_n) (x) grad phi_n = R^T sum_n x_n (x) grad phi_n - G0.
    const Mat3& rotation = rotations_[e];
    const StrainStress local =
        hooke(rotation.transpose() * gradient - rest_gradients_[e], shape_->lambda, shape_->mu);
    const Mat3 scaled = -volumes_[e] * rotation * local.stress;
    for (int k = 0; k < length; ++k) {
      buffer.segment<3>(3 * static_cast<Index>(neighbours_[base + k])).noalias() +=
          scaled * shape_gradients_[base + k];
    }
  });
}

void CorotationalEfg::add_stiffness_product(const Vector& p, Vector& out) const {
  accumulate(out, [&](int e, Vector& buffer) {
    const size_t base = static_cast<size_t>(e) * stride_;
    const int length = row_lengths_[e];
    Mat3 gradient = Mat3::Zero();
    for (int k = 0; k < length; ++k) {
      gradient.noalias() += p.segment<3>(3 * static_cast<Index>(neighbours_[base + k])) *
                            shape_gradients_[base + k].transpose();
    }
    const Mat3& rotation = rotations_[e];
    const StrainStress local = hooke(rotation.transpose() * gradient, shape_->lambda, shape_->mu);
    const Mat3 scaled = volumes_[e] * rotation * local.stress;
    for (int k = 0; k < length; ++k) {
      buffer.segment<3>(3 * static_cast<Index>(neighbours_[base + k])).noalias() +=
          scaled * shape_gradients_[base + k];
    }
  });
}

void CorotationalEfg::add_stiffness_diagonal(Vector& diagonal) const {
  accumulate(diagonal, [&](int e, Vector& buffer) {
    const size_t base = static_cast<size_t>(e) * stride_;
    const Mat3& rotation = rotations_[e];
    for (int k = 0; k < row_lengths_[e]; ++k) {
      // K_nn = V R (lambda g g^T + mu g g^T + mu |g|^2 I) R^T (tet_element.hpp's block with
      // a = b), whose diagonal needs only R g.
      const Vec3& g = shape_gradients_[base + k];
      const Vec3 turned = rotation * g;
      buffer.segment<3>(3 * static_cast<Index>(neighbours_[base + k])) +=
          volumes_[e] * ((shape_->lambda + shape_->mu) * turned.cwiseProduct(turned) +
                         Vec3::Constant(shape_->mu * g.squaredNorm()));
    }
  });
}

double CorotationalEfg::elastic_energy(const Vector& x) const {
  energy_positions_ = x;
  energy_orientations_.resize(static_cast<size_t>(element_count()));
  energy_valid_.assign(static_cast<size_t>(element_count()), 1);
  executor_->parallel_for(element_count(), [&](int begin, int end) {
    for (int e = begin; e < end; ++e) {
      const size_t base = static_cast<size_t>(e) * stride_;
      energy_orientations_[e] = element_rotation(x, e, orientations_[e]);
      const Mat3 rotation = energy_orientations_[e].toRotationMatrix();
      Mat3 gradient = Mat3::Zero();
      for (int k = 0; k < row_lengths_[e]; ++k) {
        gradient += x.segment<3>(3 * static_cast<Index>(neighbours_[base + k])) *
                    shape_gradients_[base + k].transpose();
      }
      const StrainStress local =
          hooke(rotation.transpose() * gradient - rest_gradients_[e], shape_->lambda, shape_->mu);
      // W = 1/2 sigma : eps = mu eps : eps + lambda / 2 tr(eps)^2.
      element_energies_[e] = 0.5 * volumes_[e] * (local.stress.cwiseProduct(local.strain)).sum();
    }
  }, std::max(1, shape_->settings.threaded_elements / 2));
  double energy = 0;
  for (double element_energy : element_energies_) energy += element_energy;
  return energy;
}

}  // namespace incise::physics
