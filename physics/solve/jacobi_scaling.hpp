// The Jacobi scaling D^-1 of the V-cycle's Chebyshev smoother (multigrid.hpp): the inverse of
// the system's diagonal, or of its 3x3 node blocks (point-block Jacobi).
//
// The node blocks couple a node's three directions, as the tissue's operator does: at nu = 0.45
// (lambda = 9 mu) a node's block is far from diagonal in the frame of the axes. With them the
// degree-4 cycle damps more of the fine error for the same products: `bench performance
// --quick`, mean CG iterations over the 200 solves of a size, diagonal -> node blocks: 20248
// elements 7.19 -> 6.12 (the cutting steps 7.46 -> 6.28), 3948 4.94 -> 4.28. And a block
// scaling turns with the nodes: R B R^T's inverse is R B^-1 R^T, so the spectrum of B^-1 A
// barely moves as the body turns, and the rest system's estimate of its top
// (RestFactor::node_block_eigenvalue) bounds the current one closely, where the diagonal's
// moves with every rotation (the scalar cycle's 1.2 margin).
#pragma once

#include "physics/core/executor.hpp"
#include "physics/core/model.hpp"

#include <Eigen/Core>

#include <cstddef>
#include <utility>
#include <vector>

namespace incise::physics {

class JacobiScaling {
 public:
  JacobiScaling() = default;
  // The diagonal's inverse (jacobi_inverse); implicit, so a vector still makes one.
  JacobiScaling(Vector inverse_diagonal) : inverse_diagonal_(std::move(inverse_diagonal)) {}  // NOLINT
  // The inverse of each node's block of A (fixed nodes: the identity), each made exactly
  // symmetric (the smoother's S = p(B^-1 A) B^-1 must be symmetric for CG).
  static JacobiScaling node_blocks(const std::vector<Mat3>& blocks, Executor& executor = serial_executor());

  // out = D^-1 r over the entries [begin, end) (whole nodes with blocks). Each entry is computed
  // in the one order written here, so every caller gets the same bits.
  void apply(const double* r, double* out, Eigen::Index begin, Eigen::Index end) const {
    if (inverse_blocks_.empty()) {
      const double* inverse = inverse_diagonal_.data();
      for (Eigen::Index i = begin; i < end; ++i) out[i] = inverse[i] * r[i];
      return;
    }
    for (Eigen::Index node = begin / 3; node < end / 3; ++node) {
      const Mat3& b = inverse_blocks_[static_cast<std::size_t>(node)];
      const double r0 = r[3 * node], r1 = r[3 * node + 1], r2 = r[3 * node + 2];
      for (int a = 0; a < 3; ++a) out[3 * node + a] = b(a, 0) * r0 + b(a, 1) * r1 + b(a, 2) * r2;
    }
  }

 private:
  Vector inverse_diagonal_;
  std::vector<Mat3> inverse_blocks_;
};

// B^-1/2 per node of a symmetric positive definite block (its eigen decomposition): the
// symmetric scaling of the node-block Lanczos estimate (multigrid.hpp).
Mat3 inverse_square_root(const Mat3& block);

}  // namespace incise::physics
