// An assembled implicit system in 3x3 blocks (block CSR, both triangles stored):
//   A0 = mass_coefficient M + stiffness_coefficient K0,
// the rows and columns of fixed nodes replaced by the identity's, as BlockMatrix::system
// builds it in scalar form. The V-cycle's smoother multiplies by it (multigrid.hpp): one
// product reads 9 numbers per block of the node graph, several times less work than the
// model's matrix-free product, which visits every integration point's neighbourhood twice.
//
// The blocks are kept in double, or rounded once to float (`single`: half the memory; the
// sums stay double, so the product is that of a fixed symmetric matrix, A0 with every entry
// rounded, and as deterministic). The product (block_product.hpp) splits the block rows into
// fixed ranges; each row is summed by one thread in column order, so the result does not
// depend on the thread count.
#pragma once

#include "physics/core/executor.hpp"
#include "physics/solve/block_matrix.hpp"

#include <Eigen/Core>

#include <cstdint>
#include <vector>

namespace incise::physics {

class BlockSystem {
 public:
  BlockSystem() = default;
  BlockSystem(const BlockMatrix& stiffness, const Eigen::VectorXd& masses, const std::vector<std::uint8_t>& fixed,
              double mass_coefficient, double stiffness_coefficient, bool single = false);

  int nodes() const { return row_start_.empty() ? 0 : static_cast<int>(row_start_.size()) - 1; }
  bool single() const { return !single_blocks_.empty(); }
  // y = A0 x (x and y of size 3 nodes, distinct), its rows on `executor`'s threads.
  void multiply(const Eigen::VectorXd& x, Eigen::VectorXd& y, Executor& executor) const;
  // residual -= A0 x, row by row (the same bits as y = A0 x; residual -= y).
  void subtract_product(const Eigen::VectorXd& x, Eigen::VectorXd& residual, Executor& executor) const;
  // The scalar diagonal of A0 (of the rounded blocks when single).
  Eigen::VectorXd diagonal() const;
  // Its node blocks on the diagonal, one a node (the identity's on fixed nodes).
  std::vector<Mat3> diagonal_blocks() const;
  // Rounds a double system's blocks to float: then as if built with `single` (the rest factor
  // first estimates its smoothing bound on the double one).
  void round_to_single();

 private:
  void rows(const Eigen::VectorXd& x, Eigen::VectorXd& y, Executor& executor, bool subtract) const;
  Mat3 block(int k) const;

  std::vector<int> row_start_;  // nodes + 1
  std::vector<int> columns_;
  // Block (row, columns_[k]) at 9 k, in block_product.hpp's lane order, one scalar of padding
  // at the end; one of the two is filled.
  std::vector<double> blocks_;
  std::vector<float> single_blocks_;
};

}  // namespace incise::physics
