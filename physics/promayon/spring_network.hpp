// The classical mass-spring of the seed's comparisons (seed 002 §1.2): one spring
// F = k_r (|X_iX_j| - l0) X_iX_j / |X_iX_j| per pair of lattice neighbours (VN1 or Moore), the
// baseline the shape memory is measured against. Optionally a dashpot on each spring (damping
// of the relative velocity along it), the classical network's per-spring damping that the
// 3-atom stability test (§1.3, §5.2) sets against the shape memory's per-atom -k_a v.
//
// As a DeformableModel: update_rotations(x) freezes each spring's direction and length; K is
// the spring tangent with its transverse part clamped at zero under compression (PSD).
#pragma once

#include "physics/core/model.hpp"

#include <memory>
#include <vector>

namespace incise::physics {

struct NetworkSpring {
  int a = 0, b = 0;
  double rest_length = 0;
};

class SpringNetwork final : public DeformableModel {
 public:
  // Each neighbour pair once, stiffness k_r (N/m) and dashpot (N s/m, 0: none) on every spring.
  // Throws std::invalid_argument on a bad stiffness or mass, or a zero-length spring.
  SpringNetwork(const Vector& rest, const std::vector<std::vector<int>>& neighbours, const Vector& masses,
                double stiffness, double dashpot, double spacing);

  int node_count() const override { return static_cast<int>(masses_.size()); }
  const Vector& rest_positions() const override { return rest_; }
  const Vector& lumped_masses() const override { return masses_; }
  void update_rotations(const Vector& x) override;
  void add_elastic_forces(const Vector& x, Vector& f) const override;
  void add_stiffness_product(const Vector& p, Vector& out) const override;
  void add_stiffness_diagonal(Vector& diag) const override;
  double elastic_energy(const Vector& x) const override;
  bool has_damping() const override { return dashpot_ > 0; }
  void add_damping_product(const Vector& p, Vector& out) const override;
  void add_damping_diagonal(Vector& diag) const override;
  double node_spacing() const override { return spacing_; }
  std::unique_ptr<DeformableModel> clone() const override { return std::make_unique<SpringNetwork>(*this); }

  const std::vector<NetworkSpring>& springs() const { return springs_; }
  double stiffness() const { return stiffness_; }

 private:
  Vector rest_;
  Vector masses_;
  double stiffness_ = 0, dashpot_ = 0, spacing_ = 0;
  std::vector<NetworkSpring> springs_;
  std::vector<Mat3> tangent_;    // per spring, frozen by update_rotations
  std::vector<Vec3> direction_;  // per spring, its unit direction frozen by update_rotations
};

}  // namespace incise::physics
