// An assembled implicit system in 3x3 blocks (block CSR, both triangles stored):
//   A0 = mass_coefficient M + stiffness_coefficient K0,
// the rows and columns of fixed nodes replaced by the identity's, as BlockMatrix::system
// builds it in scalar form. The V-cycle's smoother multiplies by it (multigrid.hpp): one
// product reads 9 doubles per block of the node graph, several times less work than the
// model's matrix-free product, which visits every integration point's neighbourhood twice.
//
// The product splits the block rows into fixed ranges; each row is summed by one thread in
// column order, so the result does not depend on the thread count.
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
              double mass_coefficient, double stiffness_coefficient);

  int nodes() const { return static_cast<int>(row_start_.size()) - 1; }
  // y = A0 x (x and y of size 3 nodes, distinct), its rows on `executor`'s threads.
  void multiply(const Eigen::VectorXd& x, Eigen::VectorXd& y, Executor& executor) const;
  // The scalar diagonal of A0.
  Eigen::VectorXd diagonal() const;

 private:
  std::vector<int> row_start_;  // nodes + 1
  std::vector<int> columns_;
  std::vector<Mat3> blocks_;    // block (row, columns_[k]) at k
};

}  // namespace incise::physics
