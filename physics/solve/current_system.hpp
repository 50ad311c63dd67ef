// The implicit step's current system in 3x3 blocks, on the assembled corotated stiffness K(x)
// (DeformableModel::current_stiffness, K with the step's frozen rotations):
//   A = mass_coefficient M + stiffness_coefficient (K + K_springs),
// the rows and columns of fixed nodes replaced by the identity's. On the free degrees of
// freedom its product is the matrix-free one of implicit_euler_step to round-off, at about a
// quarter of its cost (no integration point visited); CG and the V-cycle's smoother
// (multigrid.hpp) both multiply by it (solver.preconditioner "multigrid_current").
//
// The matrix is referenced, not copied: the masses, the springs and the fixed nodes are
// applied in the product, one pass of current_product.hpp's kernel that reads K's blocks in
// place (AVX2 where the CPU has it, same bits as Eigen's `sum += block * x` it replaced).
// Each row is summed by one thread in column order, so the product does not depend on the
// thread count.
#pragma once

#include "physics/core/executor.hpp"
#include "physics/core/model.hpp"
#include "physics/solve/current_product.hpp"

#include <cstdint>
#include <span>
#include <vector>

namespace incise::physics {

class CurrentSystem {
 public:
  // All referenced arguments must outlive the system.
  CurrentSystem(const BlockMatrix& stiffness, const Vector& masses, const std::vector<std::uint8_t>& fixed,
                std::span<const NodalSpring> springs, double mass_coefficient, double stiffness_coefficient);
  // (The fixed flags are kept by reference: a temporary would dangle.)
  CurrentSystem(const BlockMatrix& stiffness, const Vector& masses, std::vector<std::uint8_t>&& fixed,
                std::span<const NodalSpring> springs, double mass_coefficient, double stiffness_coefficient) = delete;

  // y = A x (3n), its rows on `executor`'s threads.
  void multiply(const Vector& x, Vector& y, Executor& executor) const;
  // y[k] = A x[k] for each k, each bitwise multiply()'s, in one pass over K: a range's rows
  // a few at a time, every vector's product of them while their blocks are in the first- and
  // second-level caches (CG's start multiplies the last four solutions; at 75k EFG elements K
  // is 20 MB and its four reads from memory were 3.3 ms of the step).
  void multiply_several(std::span<const Vector> x, std::span<Vector> y, Executor& executor) const;
  // y's rows [begin, end) (nodes) of A x, x zero on the fixed nodes: the kernel of multiply()
  // on one range, for a caller that fuses its own work with the rows' product
  // (current_vcycle.hpp).
  void multiply_rows(const double* x, double* y, int begin, int end) const;
  int block_count() const { return stiffness_.block_count(); }
  // The scalar diagonal of A (1 on fixed nodes).
  Vector diagonal() const;
  // A's 3x3 blocks on the diagonal, one a node (the identity's on fixed nodes).
  std::vector<Mat3> diagonal_blocks(Executor& executor = serial_executor()) const;
  int nodes() const { return stiffness_.nodes(); }
  bool is_fixed(int node) const { return !fixed_.empty() && fixed_[static_cast<size_t>(node)] != 0; }

  // The product kernel's view of A (current_product.hpp): K's rows, masses, springs, fixed rows.
  CurrentRows rows() const;

 private:
  // K's diagonal block of `row` with its springs'.
  Mat3 free_diagonal_block(int row) const;
  // x's entries as the kernel reads them: x itself, or `zeroed` (x zeroed on the fixed nodes).
  const double* free_entries(const Vector& x, Vector& zeroed) const;

  const BlockMatrix& stiffness_;
  const Vector& masses_;
  const std::vector<std::uint8_t>& fixed_;
  double mass_coefficient_, stiffness_coefficient_;
  // Per node, the sum of its springs' stiffnesses (all zero without springs).
  std::vector<Mat3> spring_blocks_;
  std::vector<int> fixed_nodes_;  // the nodes marked fixed, in order
};

}  // namespace incise::physics
