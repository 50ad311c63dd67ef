// Promayon's volumetric shape memory, "discrete deformation coordinates" (Marchal 2006; seed
// 002 §1.4). Each atom P keeps, for every triplet <N_a, N_b, N_c> of its neighbours that is not
// collinear, the barycentric coordinates (alpha_a, alpha_b, alpha_c) of its orthogonal
// projection Q_t on the triplet's plane and its signed distance beta_t to that plane, taken at
// rest. At run time its attractor is the mean over its m triplets
//   P* = 1/m sum_t (alpha_a N_a + alpha_b N_b + alpha_c N_c + beta_t n_t / |n_t|),
// n_t = (N_b - N_a) x (N_c - N_a) from the current positions, and it feels F = k_e (P* - P).
// The reaction -F goes to the neighbours in proportion to their linear coefficient in P*,
// w_a = 1/m sum_{t containing a} alpha_a (the w sum to 1), so the forces sum to zero: linear
// momentum is conserved (the normals' dependence on the neighbours is left out of the
// redistribution, as in the seed, so angular momentum is not exactly).
//
// The coordinates are invariant under rigid motions (barycentric coordinates under any affine
// map, the signed distance under rotations and translations), so a rigid motion of the rest
// shape gives zero force. On a lattice, more: an atom whose neighbourhood is centrally
// symmetric feels no pull under any affine map of it (a triplet and its mirror image through the
// atom keep one normal and opposite beta), so the bulk resists strain gradients only and a
// homogeneous strain is held by the boundary atoms (docs/status.md).
//
// As a DeformableModel: K = k_e B^T B, B the linear map x -> (P - sum_a w_a N_a) per atom, is
// the Jacobian with the normals frozen (symmetric PSD); it is what the implicit Euler and the
// static settle use. The seed's explicit step (seed_step.hpp) needs only the forces.
#pragma once

#include "physics/core/model.hpp"

#include <array>
#include <memory>
#include <optional>
#include <vector>

namespace incise::physics {

// Which triplets an atom keeps. all: every non-collinear one (§1.4). unmirrored: of a triplet
// and its mirror image through the atom (each neighbour offset negated, all three neighbours
// present) only one, the one whose sorted offsets are lexicographically the larger: the pair's
// normal terms cancel under any affine map, the one left does not, so an interior lattice atom
// resists a homogeneous strain too (an experiment on the finding above; the seed's "VN1*" kept
// 3872 triplets on the Truth Cube's 729 atoms, a selection it does not describe).
enum class TripletSelection { all, unmirrored };

struct Triplet {
  std::array<int, 3> atoms{};       // neighbour indices (global)
  std::array<double, 3> alpha{};    // barycentric coordinates of Q_t, summing to 1
  double beta = 0;                  // signed distance of P to the plane along n_t / |n_t|
};

class ShapeMemory final : public DeformableModel {
 public:
  // rest: 3n; neighbours: per atom; masses: n; stiffness: k_e, N/m, the same for every atom.
  // Throws std::invalid_argument naming the atom that has fewer than 3 neighbours or no
  // valid (non-collinear) triplet, or a bad stiffness / mass.
  ShapeMemory(const Vector& rest, const std::vector<std::vector<int>>& neighbours, const Vector& masses,
              double stiffness, double spacing, TripletSelection selection = TripletSelection::all);

  int node_count() const override { return static_cast<int>(masses_.size()); }
  const Vector& rest_positions() const override { return rest_; }
  const Vector& lumped_masses() const override { return masses_; }
  void update_rotations(const Vector& /*x*/) override {}
  void add_elastic_forces(const Vector& x, Vector& f) const override;
  void add_stiffness_product(const Vector& p, Vector& out) const override;
  void add_stiffness_diagonal(Vector& diag) const override;
  double elastic_energy(const Vector& x) const override;
  double node_spacing() const override { return spacing_; }
  std::unique_ptr<DeformableModel> clone() const override { return std::make_unique<ShapeMemory>(*this); }

  // Atom i's attractor P* at x.
  Vec3 attractor(const Vector& x, int i) const;
  double stiffness() const { return stiffness_; }
  std::size_t triplet_count() const;

 private:
  Vector rest_;
  Vector masses_;
  double stiffness_ = 0;
  double spacing_ = 0;
  std::vector<std::vector<int>> neighbours_;
  std::vector<std::vector<double>> weights_;   // per atom, w_a per neighbour
  std::vector<std::vector<Triplet>> normal_;   // per atom, its triplets with beta != 0
  std::vector<int> triplets_per_atom_;         // m
  Vector diagonal_;                            // diag(B^T B) per atom
};

}  // namespace incise::physics
