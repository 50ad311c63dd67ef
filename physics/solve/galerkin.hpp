// The Galerkin coarse system P^T A0 P of a coarse space (coarse_space.hpp), straight from the
// assembled 3x3 blocks, without the scalar A0 (BlockMatrix::system) or a sparse-sparse product:
//   A0 = mass_coefficient M + stiffness_coefficient K0,   P = W (x) I3,
//   (P^T A0 P)_ab = sum_i w_ia sum_j A0_ij w_jb       (3x3 blocks, a, b coarse vertices).
// Fixed nodes have no weights (their rows of P are zero), so the identity rows and columns
// BlockMatrix::system gives them drop out, as do its couplings to them.
//
// Only the lower triangle is formed, the one CHOLMOD and Eigen's LLT read (their UpLo is
// Lower). Each entry is summed as Eigen's SparseMatrix(P^T) * (A0 * P) sums it, the same
// products in the same order (over fine nodes j, then i, increasing), so the entries carry its
// bits: a factor of this matrix is the factor of that product.
#pragma once

#include "physics/solve/block_matrix.hpp"
#include "physics/solve/coarse_space.hpp"

#include <Eigen/Core>
#include <Eigen/SparseCore>

#include <cstdint>
#include <vector>

namespace incise::physics {

// The lower triangle of P^T A0 P (3m x 3m, column-major, rows increasing within a column).
// `masses`: per node; `fixed`: per node, 1 = fixed (empty: none). Throws std::invalid_argument
// when the sizes do not match the stiffness's node count.
Eigen::SparseMatrix<double> galerkin_lower(const BlockMatrix& stiffness, const Eigen::VectorXd& masses,
                                           const std::vector<std::uint8_t>& fixed, double mass_coefficient,
                                           double stiffness_coefficient, const CoarseSpace& coarse);

}  // namespace incise::physics
