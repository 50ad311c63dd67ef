// Baudet's parameterised hexahedral mass-spring model as Fléchon implements it (seed 003;
// digest seed-000-003.md B.1, C.2): per brick 12 edge springs and 4 body diagonals whose
// stiffnesses come from (E, nu) by Baudet's 3-D formulas (baudet_stiffness.hpp), a spring
// shared by several bricks created once with the sum of their stiffnesses, masses lumped from
// each brick's volume (rho V / 8 to each of its nodes), and a dashpot on every spring.
//
// As a DeformableModel for the shared implicit Euler + CG: the elastic force is the full
// nonlinear spring force; update_rotations(x) freezes each spring's direction and length,
// from which the stiffness K (the spring's tangent, its transverse part clamped at zero under
// compression so that K stays positive semi-definite) and the damping D are applied.
#pragma once

#include "physics/core/model.hpp"
#include "physics/mss/hex_mesh.hpp"

#include <memory>
#include <vector>

namespace incise::physics {

struct MassSpringMaterial {
  double youngs_modulus = 0;  // Pa
  double poisson_ratio = 0;
  double density = 0;  // kg/m^3
  // Each spring's dashpot is damping_ratio x 2 sqrt(m k) (Fléchon §2.2 after Bhasin & Liu:
  // critical damping, 1), m the reduced mass m_a m_b / (m_a + m_b) of its two nodes: the source
  // leaves the mass open; the reduced mass makes the pair's relative motion critically damped.
  double damping_ratio = 1;
};

struct Spring {
  int a = 0, b = 0;
  double rest_length = 0;
  double stiffness = 0;  // N/m, summed over the bricks that share it
  double damping = 0;    // N s/m, on the relative velocity projected on the spring
};

class HexMassSpring final : public DeformableModel {
 public:
  // Throws std::invalid_argument naming the brick (index, size, aspect ratio) whose formulas
  // give a non-positive stiffness, or a bad material.
  HexMassSpring(const HexMesh& mesh, const MassSpringMaterial& material);

  int node_count() const override { return static_cast<int>(masses_.size()); }
  const Vector& rest_positions() const override { return rest_; }
  const Vector& lumped_masses() const override { return masses_; }
  void update_rotations(const Vector& x) override;
  void add_elastic_forces(const Vector& x, Vector& f) const override;
  void add_stiffness_product(const Vector& p, Vector& out) const override;
  void add_stiffness_diagonal(Vector& diag) const override;
  double elastic_energy(const Vector& x) const override;
  bool has_damping() const override { return true; }
  void add_damping_product(const Vector& p, Vector& out) const override;
  void add_damping_diagonal(Vector& diag) const override;
  double explicit_step_limit() const override { return explicit_limit_; }
  double node_spacing() const override { return spacing_; }
  std::unique_ptr<DeformableModel> clone() const override { return std::make_unique<HexMassSpring>(*this); }

  const std::vector<Spring>& springs() const { return springs_; }
  const std::vector<std::array<int, 8>>& hexes() const { return hexes_; }
  // Per node, the summed stiffness of the springs that meet there, N/m.
  const Vector& node_stiffness() const { return node_stiffness_; }

 private:
  Vector rest_;
  Vector masses_;
  Vector node_stiffness_;
  std::vector<std::array<int, 8>> hexes_;
  std::vector<Spring> springs_;
  std::vector<Mat3> tangent_;  // per spring, K_s frozen by update_rotations
  std::vector<Vec3> direction_;  // per spring, its unit direction frozen by update_rotations
  double explicit_limit_ = 0;
  double spacing_ = 0;
};

// The explicit integrators' bound for a mass-spring network (digest B.1.1, "Caution"): 2
// sqrt(m / k) on the lightest, stiffest node, m_min / k_node_max, not the report's m_max / k_min.
double mass_spring_explicit_limit(const Vector& masses, const Vector& node_stiffness);

}  // namespace incise::physics
