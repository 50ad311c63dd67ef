// The seed's Truth-Cube set-up (seed 002 §5.1, §8.1) against incise's FEM, shared by the test
// (tests/unit/test_promayon_compression.cpp) and `incise bench accuracy`'s `compression` case:
// a 9 x 9 x 9 lattice (8 x 8 x 8 cells of side 1; the models are scale-free under prescribed
// displacements) clamped between two plates and compressed by 18.25 % of its height. Each
// discrete model is relaxed to equilibrium by the seed's step with damping; the reference is the
// quadratic-tet linear FEM of the same block (nu = 0.49, the silicone's near incompressibility),
// whose nodes include the lattice's atoms. The error is the seed's epsilon_REN over the 7^3
// interior atoms (its beads): the mean of |X - X_fem| / |X0 - X_fem| (100 % is the error of not
// moving at all).
#pragma once

#include "physics/mss/hex_mesh.hpp"
#include "physics/promayon/calibration.hpp"
#include "physics/promayon/shape_memory.hpp"
#include "physics/promayon/volume_projection.hpp"

#include <cstdint>
#include <vector>

namespace incise::physics {

class TruthCube {
 public:
  static constexpr int kCells = 8;
  static constexpr double kCompression = 0.1825;

  TruthCube();
  const HexMesh& mesh() const { return mesh_; }
  const std::vector<std::uint8_t>& fixed() const { return fixed_; }
  // The atoms with the top plate moved down.
  const Vector& start() const { return start_; }
  const Triangles& surface() const { return surface_; }
  double rest_volume() const { return rest_volume_; }
  bool interior(int atom) const;

  // The FEM's displaced positions at the atoms: quadratic tets on `fem_cells` cells per side (a
  // multiple of 4, so that every atom is a node), the plates' nodes fixed as the atoms are.
  // Throws std::invalid_argument for another count.
  Vector fem_reference(int fem_cells, double poisson_ratio) const;

 private:
  HexMesh mesh_;
  std::vector<std::uint8_t> fixed_;
  Vector start_;
  Triangles surface_;
  double rest_volume_ = 0;
};

struct CompressionResult {
  double error = 0, spread = 0;  // epsilon_REN over the interior atoms: mean and standard deviation
  double volume_change = 0;      // relative, of the block's closed surface
  int steps = 0;                 // the seed's steps to equilibrium
  bool settled = false;          // every speed below 1e-9 (per unit time) within 200 000 steps
  long long elements = 0;        // springs or triplets
  Vector positions;              // at the end
};

// The epsilon_REN (mean, spread) and the volume change of given positions.
CompressionResult truth_cube_error(const TruthCube& cube, const Vector& positions, const Vector& reference);

struct TruthCubeModel {
  PromayonKind kind = PromayonKind::shape_memory;
  Neighbourhood neighbourhood = Neighbourhood::vn1;
  bool volume_control = false;  // the exact projection onto the rest volume after every step
  TripletSelection selection = TripletSelection::all;  // the shape memory's
};

// The model (unit masses and stiffness) relaxed by the seed's symplectic step (dt 0.2, damping
// k_a 0.3 for the networks, 0.1 for the shape memory: near their slowest modes' critical values)
// from the plates' start, until every speed is below 1e-9.
CompressionResult relax_truth_cube(const TruthCube& cube, const Vector& reference, const TruthCubeModel& model);

}  // namespace incise::physics
