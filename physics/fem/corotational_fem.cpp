#include "physics/fem/corotational_fem.hpp"

#include <Eigen/LU>
#include <Eigen/SVD>
#include <limits>
#include <stdexcept>
#include <string>

#include "physics/fem/tet_element.hpp"

namespace incise::physics {

namespace {
using Index = Eigen::Index;
using Vec9 = Eigen::Matrix<double, 9, 1>;
}  // namespace

CorotationalTetFem::CorotationalTetFem(const TetMesh& mesh, const Material& material)
    : material_(material), elements_(mesh.tets), rest_(mesh.rest) {
  validate_material(material);
  if (rest_.size() % 3 != 0) {
    throw std::invalid_argument("CorotationalTetFem: rest has " + std::to_string(rest_.size()) +
                                " entries, not a multiple of 3");
  }
  const Index nodes = rest_.size() / 3;
  const double lambda = lame_lambda(material);
  const double mu = lame_mu(material);

  const size_t count = elements_.size();
  rest_inverse_shape_.resize(count);
  volumes_.resize(count);
  rest_edges_.resize(count);
  edge_stiffness_.resize(count);
  rotations_.assign(count, Mat3::Identity());
  masses_ = Vector::Zero(nodes);

  for (size_t e = 0; e < count; ++e) {
    const auto& tet = elements_[e];
    for (int node : tet) {
      if (node < 0 || node >= nodes) {
        throw std::invalid_argument("CorotationalTetFem: element " + std::to_string(e) +
                                    " refers to node " + std::to_string(node) + " outside [0, " +
                                    std::to_string(nodes) + ")");
      }
    }
    const TetRestGeometry geometry = tet_rest_geometry(
        rest_.segment<3>(3 * tet[0]), rest_.segment<3>(3 * tet[1]), rest_.segment<3>(3 * tet[2]),
        rest_.segment<3>(3 * tet[3]), static_cast<long long>(e));
    rest_inverse_shape_[e] = geometry.inverse_shape;
    volumes_[e] = geometry.volume;
    for (int a = 0; a < 3; ++a) {
      rest_edges_[e].segment<3>(3 * a) =
          rest_.segment<3>(3 * tet[a + 1]) - rest_.segment<3>(3 * tet[0]);
    }
    // grad N_a (a = 1..3) is row a - 1 of Dm^-1; K_ab = V (lambda g_a g_b^T + ...).
    for (int a = 0; a < 3; ++a) {
      const Vec3 gradient_a = geometry.inverse_shape.row(a).transpose();
      for (int b = 0; b < 3; ++b) {
        const Vec3 gradient_b = geometry.inverse_shape.row(b).transpose();
        edge_stiffness_[e].block<3, 3>(3 * a, 3 * b) =
            geometry.volume * isotropic_stiffness_block(gradient_a, gradient_b, lambda, mu);
      }
    }
    // Lumped mass: each corner carries a quarter of rho V.
    for (int node : tet) masses_[node] += 0.25 * material.density * geometry.volume;
  }
  for (Index node = 0; node < nodes; ++node) {
    if (!(masses_[node] > 0)) {
      throw std::invalid_argument("CorotationalTetFem: node " + std::to_string(node) +
                                  " belongs to no element (it would have no mass)");
    }
  }
}

Mat3 CorotationalTetFem::polar_rotation(const Mat3& deformation_gradient) {
  if (!deformation_gradient.allFinite()) {
    return Mat3::Constant(std::numeric_limits<double>::quiet_NaN());
  }
  const Eigen::JacobiSVD<Mat3> svd(deformation_gradient, Eigen::ComputeFullU | Eigen::ComputeFullV);
  Mat3 u = svd.matrixU();
  const Mat3& v = svd.matrixV();
  // Singular values are sorted decreasingly: flipping the last column of U turns a reflection
  // into the nearest rotation (Irving et al. 2004, section 5).
  if ((u * v.transpose()).determinant() < 0) u.col(2) = -u.col(2);
  return u * v.transpose();
}

Mat3 CorotationalTetFem::element_rotation(const Vector& x, size_t element) const {
  const auto& tet = elements_[element];
  const Vec3 x0 = x.segment<3>(3 * tet[0]);
  Mat3 deformed_shape;  // Ds
  deformed_shape << x.segment<3>(3 * tet[1]) - x0, x.segment<3>(3 * tet[2]) - x0,
      x.segment<3>(3 * tet[3]) - x0;
  return polar_rotation(deformed_shape * rest_inverse_shape_[element]);  // F = Ds Dm^-1
}

Vec9 CorotationalTetFem::local_edge_displacement(const Vector& x, size_t element,
                                                 const Mat3& rotation) const {
  const auto& tet = elements_[element];
  const Vec3 x0 = x.segment<3>(3 * tet[0]);
  Vec9 local;
  for (int a = 0; a < 3; ++a) {
    local.segment<3>(3 * a) = rotation.transpose() * (x.segment<3>(3 * tet[a + 1]) - x0);
  }
  return local - rest_edges_[element];
}

void CorotationalTetFem::update_rotations(const Vector& x) {
  for (size_t e = 0; e < elements_.size(); ++e) rotations_[e] = element_rotation(x, e);
}

void CorotationalTetFem::add_elastic_forces(const Vector& x, Vector& f) const {
  for (size_t e = 0; e < elements_.size(); ++e) {
    const auto& tet = elements_[e];
    const Mat3& rotation = rotations_[e];
    const Vec9 local_force = -(edge_stiffness_[e] * local_edge_displacement(x, e, rotation));
    Vec3 corner_zero = Vec3::Zero();
    for (int a = 0; a < 3; ++a) {
      const Vec3 world = rotation * local_force.segment<3>(3 * a);
      f.segment<3>(3 * tet[a + 1]) += world;
      corner_zero -= world;  // the forces of an element sum to zero
    }
    f.segment<3>(3 * tet[0]) += corner_zero;
  }
}

void CorotationalTetFem::add_stiffness_product(const Vector& p, Vector& out) const {
  for (size_t e = 0; e < elements_.size(); ++e) {
    const auto& tet = elements_[e];
    const Mat3& rotation = rotations_[e];
    const Vec3 p0 = p.segment<3>(3 * tet[0]);
    Vec9 local;
    for (int a = 0; a < 3; ++a) {
      local.segment<3>(3 * a) = rotation.transpose() * (p.segment<3>(3 * tet[a + 1]) - p0);
    }
    const Vec9 local_product = edge_stiffness_[e] * local;
    Vec3 corner_zero = Vec3::Zero();
    for (int a = 0; a < 3; ++a) {
      const Vec3 world = rotation * local_product.segment<3>(3 * a);
      out.segment<3>(3 * tet[a + 1]) += world;
      corner_zero -= world;
    }
    out.segment<3>(3 * tet[0]) += corner_zero;
  }
}

void CorotationalTetFem::add_stiffness_diagonal(Vector& diagonal) const {
  for (size_t e = 0; e < elements_.size(); ++e) {
    const auto& tet = elements_[e];
    const Mat3& rotation = rotations_[e];
    const EdgeStiffness& stiffness = edge_stiffness_[e];
    // K_00 = sum_ab K_ab over corners 1..3 (from K_0b = -sum_a K_ab).
    Mat3 corner_zero_block = Mat3::Zero();
    for (int a = 0; a < 3; ++a) {
      for (int b = 0; b < 3; ++b) corner_zero_block += stiffness.block<3, 3>(3 * a, 3 * b);
    }
    diagonal.segment<3>(3 * tet[0]) +=
        (rotation * corner_zero_block * rotation.transpose()).diagonal();
    for (int a = 0; a < 3; ++a) {
      const Mat3 block = stiffness.block<3, 3>(3 * a, 3 * a);
      diagonal.segment<3>(3 * tet[a + 1]) += (rotation * block * rotation.transpose()).diagonal();
    }
  }
}

double CorotationalTetFem::elastic_energy(const Vector& x) const {
  double energy = 0;
  for (size_t e = 0; e < elements_.size(); ++e) {
    const Vec9 local = local_edge_displacement(x, e, element_rotation(x, e));
    energy += 0.5 * local.dot(edge_stiffness_[e] * local);
  }
  return energy;
}

}  // namespace incise::physics
