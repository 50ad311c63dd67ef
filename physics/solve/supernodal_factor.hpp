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
//
// The solve runs on two threads where that pays: the supernodes' elimination tree is split
// once, when the factor is read, into two parts of about equal work (whole subtrees) and the
// top above them (the separators they share). The parts eliminate beside each other, each
// summing what it takes from the top's rows apart, then the top follows; backward, the top
// first, then the parts beside each other. The split, not the threads, fixes the order of every
// sum. A part must hold `minimum_part_work` block entries to pay for handing it to the other
// thread: the 75458-element lobe's coarse factor (parts ~0.49M entries each, the top ~1.0M)
// solves in 1.29-1.31 ms split against 1.41-1.9 serial; the 20248 one's (parts ~0.1M, the top
// ~0.16M) in 0.17-0.21 split against 0.13 serial, so it stays serial.
#pragma once

#include "physics/core/executor.hpp"

#include <Eigen/SparseCore>

#include <array>

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
  static SupernodalFactor with_cholmod(const Eigen::SparseMatrix<double>& lower, bool single_precision,
                                       std::int64_t minimum_part_work = default_minimum_part_work);
  static SupernodalFactor with_simplicial(const Eigen::SparseMatrix<double>& lower, bool single_precision,
                                          std::int64_t minimum_part_work = default_minimum_part_work);
  static constexpr std::int64_t default_minimum_part_work = 250'000;
  // Copies the layout, its entries rounded to float with `single_precision` (throws
  // std::invalid_argument if it is not one: sizes, orders, a diagonal entry not positive and
  // finite), and splits its tree (above).
  SupernodalFactor(const SupernodalLayout& layout, bool single_precision,
                   std::int64_t minimum_part_work = default_minimum_part_work);

  int size() const { return size_; }
  int supernodes() const { return first_column_.empty() ? 0 : static_cast<int>(first_column_.size()) - 1; }
  std::int64_t factor_nonzeros() const { return factor_nonzeros_; }  // L's, as its builder counts them
  // The solve's scratch (one per concurrent caller), sized by solve().
  struct Workspace {
    std::vector<double> z;
    std::array<std::vector<double>, 2> buffers, top_sums;
  };
  // x <- (P^T L' L'^T P)^-1 x (size() entries), the two parts on `executor`'s threads
  // (run_beside); the bits are the same on any executor.
  void solve(double* x, Workspace& work, Executor& executor = serial_executor()) const;
  // The smallest and the largest pivot, L_kk^2 (a free rigid mode shows as a smallest one at
  // round-off level against the largest).
  std::array<double, 2> pivot_range() const;
  // The work (block entries) of the two parts and of the top, as split (all in part 0 when a
  // part would have less than the minimum).
  std::array<std::int64_t, 3> split_work() const { return split_work_; }

 private:
  // Supernode s: its first column, columns, rows, row indices and its block's offset.
  struct Supernode {
    int first, columns, rows;
    const int* indices;
    std::int64_t values;
  };
  Supernode supernode(int s) const;
  // Splits the elimination tree (parts_, in_top_, top_columns_).
  void split(std::int64_t minimum_part_work);
  // One supernode of z <- L'^-1 z (its rows below in the top to `top_sums` when given) and of
  // z <- L'^-T z, `buffer` its rows (tallest_).
  template <typename Scalar>
  void forward_supernode(const Scalar* values, int s, double* z, double* buffer, double* top_sums) const;
  template <typename Scalar>
  void backward_supernode(const Scalar* values, int s, double* z, double* buffer) const;
  template <typename Scalar>
  void sweep(const Scalar* values, double* z, Workspace& work, Executor& executor) const;

  int size_ = 0;
  std::vector<int> permutation_;
  std::vector<int> first_column_, row_start_, row_indices_;
  std::vector<std::int64_t> value_start_;
  // The blocks, one of the two (their diagonal entries unused: inverse_diagonal_).
  std::vector<float> single_values_;
  std::vector<double> double_values_;
  std::vector<double> inverse_diagonal_;  // 1 / L_kk, per column
  std::int64_t factor_nonzeros_ = 0;
  // The split: the supernodes of part 0, part 1 and the top, each in increasing order; per
  // column whether its supernode is in the top, and the top's columns.
  std::array<std::vector<int>, 3> parts_;
  std::vector<std::uint8_t> in_top_;
  std::vector<int> top_columns_;
  std::array<std::int64_t, 3> split_work_{};
  int tallest_ = 0;                       // the most rows a supernode has
};

}  // namespace incise::physics
