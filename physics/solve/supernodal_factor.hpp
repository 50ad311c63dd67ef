// A sparse Cholesky factor, P A P^T = L L^T, kept in supernodes and solved by incise's own
// loops: the coarse correction of every V-cycle (rest_factor.hpp) is one solve with it.
//
// CHOLMOD builds the factor (or, under ThreadSanitizer, Eigen's simplicial LLT: each column a
// supernode of one); its own solve was the cycle's largest serial part, 2.0 ms of a 5.4 ms
// cycle on the 76k lobe (14.3k coarse unknowns), 0.2-0.29 of 0.94 at 20k: per supernode a
// BLAS call with one right-hand side, a dense result allocated per solve, and the factor read
// in double. Here each supernode's off-diagonal rows are one dense pass over its column-major
// block; a coarse correction's factor is stored in float (half the bytes) with its diagonal in
// double: the solve is then exactly that of the factor L' = L rounded, (L' L'^T)^-1, a fixed
// SPD operator within ~1e-7 relative of A^-1 per entry of L, as good a coarse correction (a
// whole system's factor, the `warped_cholesky` preconditioner, stays double: exact up to
// round-off for a rigidly turned body).
// Every sum is double and in a fixed order, so the bits do not depend on anything but the
// factor and the right-hand side.
#pragma once

#include <Eigen/SparseCore>

#include <cstdint>
#include <span>
#include <vector>

namespace incise::physics {

// A factor's layout as its builder hands it over (CHOLMOD's supernodal fields; a simplicial
// factor's columns, one a supernode): supernode s has columns [first_column[s],
// first_column[s + 1]), rows row_indices[row_start[s] ..) (its own columns first, in order,
// then the rows below), and its nrow x ncol block, column-major, at values[value_start[s]].
struct SupernodalLayout {
  int size = 0;
  std::span<const int> permutation;   // row k of P A P^T is row permutation[k] of A
  std::span<const int> first_column;  // supernodes + 1
  std::span<const int> row_start;     // supernodes + 1
  std::span<const int> row_indices;
  std::span<const std::int64_t> value_start;  // supernodes + 1 (the blocks' offsets)
  std::span<const double> values;
};

class SupernodalFactor {
 public:
  SupernodalFactor() = default;
  // The factor of the SPD matrix whose lower triangle is `lower`, by CHOLMOD's supernodal LL^T
  // (which runs on the BLAS's threads: see use_single_threaded_blas) or by Eigen's simplicial
  // LLT (AMD ordering; no BLAS, no threads). Throws std::runtime_error if the matrix is not
  // positive definite.
  static SupernodalFactor with_cholmod(const Eigen::SparseMatrix<double>& lower, bool single_precision);
  static SupernodalFactor with_simplicial(const Eigen::SparseMatrix<double>& lower, bool single_precision);
  // Copies the layout, its entries rounded to float with `single_precision` (throws
  // std::invalid_argument if it is not one: sizes, orders, a diagonal entry not positive and
  // finite).
  SupernodalFactor(const SupernodalLayout& layout, bool single_precision);

  int size() const { return size_; }
  int supernodes() const { return first_column_.empty() ? 0 : static_cast<int>(first_column_.size()) - 1; }
  std::int64_t factor_nonzeros() const { return factor_nonzeros_; }  // L's, as its builder counts them
  // x <- (P^T L' L'^T P)^-1 x (size() entries), `work` resized as needed.
  void solve(double* x, std::vector<double>& work) const;

 private:
  // z <- L'^-1 z and z <- L'^-T z, `buffer` a supernode's rows (tallest_).
  template <typename Scalar>
  void forward(const Scalar* values, double* z, double* buffer) const;
  template <typename Scalar>
  void backward(const Scalar* values, double* z, double* buffer) const;

  int size_ = 0;
  std::vector<int> permutation_;
  std::vector<int> first_column_, row_start_, row_indices_;
  std::vector<std::int64_t> value_start_;
  // The blocks, one of the two (their diagonal entries unused: inverse_diagonal_).
  std::vector<float> single_values_;
  std::vector<double> double_values_;
  std::vector<double> inverse_diagonal_;  // 1 / L_kk, per column
  std::int64_t factor_nonzeros_ = 0;
  int tallest_ = 0;                       // the most rows a supernode has
};

}  // namespace incise::physics
