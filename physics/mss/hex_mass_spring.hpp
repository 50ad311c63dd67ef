// Baudet's parameterised hexahedral mass-spring model as Fléchon implements it (seed 003;
// digest seed-000-003.md B.1, C.2): per brick 12 edge springs and 4 body diagonals whose
// stiffnesses come from (E, nu) by Baudet's 3-D formulas (baudet_stiffness.hpp), a spring
// shared by several bricks created once with the sum of their stiffnesses, masses lumped from
// each brick's volume (rho V / 8 to each of its nodes), and a dashpot on every spring.
//
// As a DeformableModel for the shared implicit Euler + CG: the elastic force is the full
// nonlinear spring force; update_rotations(x) freezes each spring's direction and length,
// from which the stiffness K (the spring's tangent, its transverse part clamped at zero under
// compression so that K stays positive semi-definite) and the damping D are applied. With
// corrections, their non-symmetric derivative is the step's extra stiffness
// (physics/core/extra_stiffness.hpp), and the step is solved by BiCGSTAB.
#pragma once

#include "physics/core/extra_stiffness.hpp"
#include "physics/core/model.hpp"
#include "physics/mss/baudet_stiffness.hpp"
#include "physics/mss/hex_mesh.hpp"

#include <Eigen/SparseCore>

#include <memory>
#include <vector>

namespace incise::physics {

// How the implicit step takes the derivative of Baudet's corrections, K_c = -d(corrections)/dx
// (non-symmetric: the corrections are no potential's gradient). `full` by measurement
// (test_mass_spring_implicit, docs/status.md): dt = 10 s steps reach the static solve's
// equilibrium in the fewest steps (12 and 8 against the symmetric part's 17 and 8; explicit: 21,
// and diverging at nu 0.45), and the stability sweep with corrections on keeps 44 of 54
// implicit runs stable (symmetric part 29, explicit 18). The others are for that comparison.
enum class CorrectionTangent {
  explicit_forces,  // left out: the corrections ride explicitly in the step
  symmetric,        // (K_c + K_c^T) / 2 added to the CG's matrix
  full,             // K_c itself, the step solved by BiCGSTAB
};

struct MassSpringMaterial {
  double youngs_modulus = 0;  // Pa
  double poisson_ratio = 0;
  double density = 0;  // kg/m^3
  // Each spring's dashpot is damping_ratio x 2 sqrt(m k) (Fléchon §2.2 after Bhasin & Liu:
  // critical damping, 1), m the reduced mass m_a m_b / (m_a + m_b) of its two nodes: the source
  // leaves the mass open; the reduced mass makes the pair's relative motion critically damped.
  double damping_ratio = 1;
  // Baudet's correction forces (add_correction_forces); off: springs only.
  bool corrections = false;
  CorrectionTangent correction_tangent = CorrectionTangent::full;
};

struct Spring {
  int a = 0, b = 0;
  double rest_length = 0;
  double stiffness = 0;  // N/m, summed over the bricks that share it
  double damping = 0;    // N s/m, on the relative velocity projected on the spring
};

class HexMassSpring final : public DeformableModel, public ExtraStiffness {
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
  // The corrections' derivative at the frozen positions, as correction_tangent asks.
  bool has_extra_stiffness() const override;
  bool extra_stiffness_symmetric() const override { return tangent_mode_ != CorrectionTangent::full; }
  void add_extra_stiffness_product(const Vector& p, Vector& out) const override;
  void add_extra_stiffness_diagonal(Vector& diag) const override;
  double explicit_step_limit() const override { return explicit_limit_; }
  double node_spacing() const override { return spacing_; }
  std::unique_ptr<DeformableModel> clone() const override { return std::make_unique<HexMassSpring>(*this); }

  // Baudet's correction forces, which the springs alone cannot give (digest B.1.3): for a load
  // F_i along the brick's axis i, F_ij = correction(i, j) F_i along each other axis j, applied
  // as 2 F_ij on each of its 8 nodes (the factor 2 of the Lagrangian's 8 F (2 eps) term),
  // outward from the brick's mid-plane, along the node's current edge on axis j (Fléchon §5.1:
  // the corrections follow the deformation). Under general loading F_i is the brick's axial
  // load that balances half of it: the force S_i its share of the springs carries across its
  // mid-plane normal to i, plus the corrections along i on that half's 4 nodes, which depend on
  // the other loads: F = S - 8 C^T F, solved per brick (axial_loads). In a traction test this is
  // the applied load along the pull and zero across it, exactly. Added by add_elastic_forces
  // when the material asks for them; not in K (the springs' tangent) but in the implicit step's
  // matrix through the extra stiffness (correction_tangent), and they conserve momentum (each
  // edge's two nodes get opposite forces).
  void add_correction_forces(const Vector& x, Vector& f) const;
  // Brick e's share of them, on its 8 nodes in the local order (24 values).
  Eigen::Matrix<double, 24, 1> brick_correction_forces(const Vector& x, std::size_t e) const;
  // Brick e's axial loads F_x, F_y, F_z at x (tension positive), N.
  Vec3 axial_loads(const Vector& x, std::size_t e) const;

  using BrickMatrix = Eigen::Matrix<double, 24, 24>;
  // Per brick, K_c = -d(its corrections)/d(its 8 nodes) at the positions frozen by
  // update_rotations (central differences, step 1e-7 x the node spacing: the corrections are
  // smooth and each brick's depend on its own nodes only). Computed on first use after
  // update_rotations, so that the explicit integrators, which never ask, do not pay for it (the
  // first use writes the cache: one thread per model, as the step is).
  const std::vector<BrickMatrix>& correction_tangents() const;
  // K_c of every brick as triplets of the 3n x 3n matrix (the static solve's Newton tangent).
  void add_correction_triplets(std::vector<Eigen::Triplet<double>>& out) const;

  // K (the springs' tangent frozen by update_rotations, as add_stiffness_product applies it) as
  // triplets of the 3n x 3n matrix, for a sparse direct solve (mss_static.hpp).
  void add_stiffness_triplets(std::vector<Eigen::Triplet<double>>& out) const;

  bool corrections() const { return corrections_; }
  const std::vector<Spring>& springs() const { return springs_; }
  const std::vector<std::array<int, 8>>& hexes() const { return hexes_; }
  // Per node, the summed stiffness of the springs that meet there, N/m.
  const Vector& node_stiffness() const { return node_stiffness_; }

 private:
  Vector rest_;
  Vector masses_;
  Vector node_stiffness_;
  std::vector<std::array<int, 8>> hexes_;
  std::vector<BrickSprings> bricks_;  // per brick, its own stiffnesses and correction ratios
  std::vector<Mat3> load_from_springs_;  // per brick, (I + 8 C^T)^-1 (axial_loads)
  bool corrections_ = false;
  CorrectionTangent tangent_mode_ = CorrectionTangent::full;
  Vector frozen_;  // the positions update_rotations froze
  mutable std::vector<BrickMatrix> correction_tangent_;  // per brick, K_c at frozen_ (lazy)
  mutable bool correction_tangent_stale_ = true;
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
