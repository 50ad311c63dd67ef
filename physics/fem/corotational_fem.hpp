// Corotational linear tetrahedral FEM (Mueller & Gross 2004; Irving et al. 2004 for the
// rotation from the polar decomposition of F).
//
// Per element e with rotation R_e (frozen between update_rotations calls):
//   f_e = -R_e K_e (R_e^T x_e - X_e),   K p = R_e K_e R_e^T p,
//   E_e = 1/2 (R_e^T x_e - X_e)^T K_e (R_e^T x_e - X_e)
// with K_e the small-strain stiffness of the rest element.
#pragma once

#include <Eigen/Core>
#include <array>
#include <memory>
#include <vector>

#include "physics/core/model.hpp"
#include "physics/fem/material.hpp"
#include "physics/fem/tet_mesh.hpp"

namespace incise::physics {

class CorotationalTetFem final : public DeformableModel {
 public:
  // Throws std::invalid_argument on an invalid material, an out-of-range node index, a node
  // used by no element (it would have no mass), or a degenerate or inverted rest element
  // (the message names the element index).
  CorotationalTetFem(const TetMesh& mesh, const Material& material);

  int node_count() const override { return static_cast<int>(masses_.size()); }
  const Vector& rest_positions() const override { return rest_; }
  const Vector& lumped_masses() const override { return masses_; }
  void update_rotations(const Vector& x) override;
  void add_elastic_forces(const Vector& x, Vector& f) const override;
  void add_stiffness_product(const Vector& p, Vector& out) const override;
  void add_stiffness_diagonal(Vector& diagonal) const override;
  // Uses rotations computed from x itself (not the frozen ones), so the energy is invariant
  // under rigid motions of x.
  double elastic_energy(const Vector& x) const override;
  std::function<BlockMatrix()> rest_stiffness_job() const override;
  void node_rotations(std::vector<Eigen::Quaterniond>& out) const override;
  double node_spacing() const override;
  std::unique_ptr<DeformableModel> clone() const override { return std::make_unique<CorotationalTetFem>(*this); }

  int element_count() const { return static_cast<int>(elements_.size()); }
  const std::vector<std::array<int, 4>>& elements() const { return elements_; }
  const std::vector<double>& element_volumes() const { return volumes_; }
  const std::vector<Mat3>& rotations() const { return rotations_; }
  const Material& material() const { return material_; }

  // The rotation of the polar decomposition F = R S, made a proper rotation (det R = +1) for
  // inverted or flat elements by flipping the direction of the smallest singular value.
  static Mat3 polar_rotation(const Mat3& deformation_gradient);

 private:
  // The stiffness of corners 1..3 against corners 1..3 (9x9). Translation invariance
  // (K applied to a uniform field is zero, K symmetric) determines the rest:
  // K_0b = -sum_a K_ab, so only edge vectors relative to corner 0 are needed.
  using EdgeStiffness = Eigen::Matrix<double, 9, 9>;

  Mat3 element_rotation(const Vector& x, size_t element) const;
  // d_a = R^T (x_a - x_0) - (X_a - X_0), a = 1..3.
  Eigen::Matrix<double, 9, 1> local_edge_displacement(const Vector& x, size_t element,
                                                      const Mat3& rotation) const;

  Material material_;
  // Static data, one entry per element (structure of arrays).
  std::vector<std::array<int, 4>> elements_;
  std::vector<Mat3> rest_inverse_shape_;  // Dm^-1
  std::vector<double> volumes_;
  std::vector<Eigen::Matrix<double, 9, 1>> rest_edges_;  // X_a - X_0, a = 1..3
  std::vector<EdgeStiffness> edge_stiffness_;
  Vector rest_;
  Vector masses_;
  // Per-step data.
  std::vector<Mat3> rotations_;
};

}  // namespace incise::physics
