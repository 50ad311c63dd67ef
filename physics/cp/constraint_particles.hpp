// Dionne's generalised particle system (seed 000, digest seed-000-003.md A.1, C.1): the nodes
// of a tetrahedral mesh are particles with lumped masses (each tet gives rho |V| / 4 to each of
// its corners), held by soft constraints with energy k C^2 / 2 (physics/cp/constraints.hpp):
// a distance constraint on every unique tet edge, an area constraint on the surface triangles
// (or on every unique tet face, as in the thesis's cube), a signed-volume constraint on every
// tet. Fixed (kinematic) particles have w = 1/m = 0: the integrators hold them and the stretch
// limiter moves only the free end of an edge.
//
// As a DeformableModel: add_elastic_forces is the full force sum -k C grad C; update_rotations(x)
// freezes each constraint's gradient, from which the stiffness is the Gauss-Newton part
// K = sum k grad C grad C^T (symmetric PSD, what the implicit step needs; the k C hess C part,
// indefinite, is left out) and the damping D (both of the thesis's variants, linear in v):
//   relative      (eq. 1.14) on every edge, f_i = -c (v_i - v_j): a graph Laplacian;
//   constraint    (eq. 1.16, Teschner) on every constraint, f_a = -c (sum_b grad_b C . v_b) grad_a C,
//                 which leaves rigid motion undamped.
// The thesis's step (Alg. 3.2) is constraint_particles_step (cp_step.hpp).
#pragma once

#include "physics/core/explicit_integrators.hpp"
#include "physics/core/model.hpp"
#include "physics/cp/constraints.hpp"
#include "physics/fem/tet_mesh.hpp"

#include <array>
#include <memory>
#include <string>
#include <vector>

namespace incise::physics {

enum class ParticleDamping { relative, constraint };

// How the settings' stiffnesses become each constraint's k.
//   per_constraint  the thesis's: every distance constraint has k_D, every area one k_A, every
//                   volume one k_V (J), however many tets share an edge. A unique edge inside a
//                   block serves 2 to 6 tets but one on the skin fewer, so the skin is stiffer
//                   per volume than the bulk (up to 4 x on a box of the 5-tet split's cubes).
//   per_volume      a sum of per-tet elements: k_D and k_V are moduli (Pa), each tet t of rest
//                   volume V_t gives k_D V_t to each of its 6 edges and k_V V_t to its own
//                   volume constraint, and k_A (N/m) times its rest area goes to each area
//                   triangle (a membrane of that surface stiffness). constraint_particles.cpp
//                   says why this makes a block's stiffness independent of its size.
enum class StiffnessScaling { per_constraint, per_volume };

struct ConstraintParticleSettings {
  double density = 1000;           // kg/m^3
  double distance_stiffness = 500;  // k_D: J per constraint, or Pa per_volume; 0: no distance constraints
  double area_stiffness = 500;      // k_A: J per constraint, or N/m per_volume; 0: no area constraints
  double volume_stiffness = 500;    // k_V: J per constraint, or Pa per_volume; 0: no volume constraints
  StiffnessScaling scaling = StiffnessScaling::per_constraint;
  bool area_on_every_face = false;  // false: the surface triangles (the patient's skin); true: every unique tet face (the cube of §4.2)
  ParticleDamping damping = ParticleDamping::relative;
  double damping_coefficient = 0;  // c: N s/m (relative) or J s (constraint); 0: none
};

struct StretchEdge {
  int a = 0, b = 0;
  double rest = 0;  // D0
};

class ConstraintParticles final : public DeformableModel {
 public:
  // Throws std::invalid_argument for a bad setting (naming it) or a degenerate tet (its index
  // and volume): every rest measure must be positive.
  ConstraintParticles(const TetMesh& mesh, const ConstraintParticleSettings& settings);

  int node_count() const override { return static_cast<int>(masses_.size()); }
  const Vector& rest_positions() const override { return rest_; }
  const Vector& lumped_masses() const override { return masses_; }
  void update_rotations(const Vector& x) override;
  void add_elastic_forces(const Vector& x, Vector& f) const override;
  void add_stiffness_product(const Vector& p, Vector& out) const override;
  void add_stiffness_diagonal(Vector& diag) const override;
  double elastic_energy(const Vector& x) const override;
  bool has_damping() const override { return settings_.damping_coefficient > 0; }
  void add_damping_product(const Vector& p, Vector& out) const override;
  void add_damping_diagonal(Vector& diag) const override;
  double node_spacing() const override { return spacing_; }
  // The explicit bound min_i 2 sqrt(m_i / k_i), k_i = sum over the constraints on particle i of
  // k |grad_i C|^2 at rest (the trace of K's diagonal block, as a mass-spring's k_node is the sum
  // of its springs): 2 / omega of the particle oscillating against still neighbours. An
  // estimate, not a guarantee: with its neighbours moving, omega is up to about twice that.
  double explicit_step_limit() const override { return explicit_limit_; }
  std::unique_ptr<DeformableModel> clone() const override { return std::make_unique<ConstraintParticles>(*this); }

  const std::vector<Constraint>& constraints() const { return constraints_; }
  const std::vector<StretchEdge>& edges() const { return edges_; }
  const std::vector<std::array<int, 4>>& tets() const { return tets_; }
  const ConstraintParticleSettings& settings() const { return settings_; }
  // Tets whose signed volume at x is negative (turned inside out; the thesis warns on them).
  int inverted_tets(const Vector& x) const;
  // Sum of the tets' signed volumes at x.
  double volume(const Vector& x) const;
  // Stoermer Verlet's memory when the body steps by it (cp_step.hpp): part of the dynamic
  // state, so it lives with the model in the body's data and is copied with it.
  VerletHistory& verlet_history() { return history_; }

 private:
  ConstraintParticleSettings settings_;
  Vector rest_;
  Vector masses_;
  std::vector<std::array<int, 4>> tets_;
  std::vector<StretchEdge> edges_;       // every unique tet edge (the stretch limiter's)
  std::vector<Constraint> constraints_;  // distance, then area, then volume
  std::vector<std::array<Vec3, 4>> gradient_;  // per constraint, frozen by update_rotations
  double spacing_ = 0;
  double explicit_limit_ = 0;
  VerletHistory history_;
};

// Unique edges and unique faces of a tet mesh, in the order first met (tet by tet).
std::vector<std::array<int, 2>> unique_tet_edges(const std::vector<std::array<int, 4>>& tets);
std::vector<std::array<int, 3>> unique_tet_faces(const std::vector<std::array<int, 4>>& tets);
// Per unique edge (unique_tet_edges' order), the summed weight of the tets that share it.
std::vector<double> shared_edge_weights(const std::vector<std::array<int, 4>>& tets, const std::vector<double>& tet_weights);

// A box of cells[0] x cells[1] x cells[2] cubes, each split into 5 tets, the split alternating
// with the parity of i + j + k so that neighbouring cells' face diagonals match (the thesis's
// cube, §4.2: 9^3 nodes, 2,560 tets). Node numbering as make_box_tets; tets positively oriented.
TetMesh make_box_tets5(Vec3 min, Vec3 max, std::array<int, 3> cells);

}  // namespace incise::physics
