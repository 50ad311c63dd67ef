// The current system's stiffness K rounded to float and laid out for the V-cycle's products
// (current_vcycle.hpp), which are most of a multigrid_current solve's work: the blocks of a
// block row in pairs, each pair three 8-float rows
//   [ row i of block k (3 floats), 0, row i of block k + 1 (3 floats), 0 ],  i = 0, 1, 2,
// and the operand x in float, 4 a node (the 4th zero). Row i of a pair times its two nodes'
// operands is one 8-lane fused multiply-add into the row's accumulator for y_i; the lanes are
// summed once a row. Against the kernel it replaced (K's blocks rounded to float in K's
// layout, each block's three columns widened, multiplied and blended in double, as
// current_product.cpp still does on the double K) this halves the instructions a block, and at
// 20k elements the product is bound by instructions, not bytes (that kernel ran as fast with
// its 3 MB copy shrunk into the first-level caches).
//
// The sums are float: y_i = ((l0 + l4) + (l1 + l5)) + ((l2 + l6) + (l3 + l7)) of the lanes, each
// lane a chain of fused multiply-adds in the row's pair order; the AVX2 + FMA kernel and the
// portable one (std::fma on floats, correctly rounded like the instruction) give the same bits.
// The mass, the springs and the fixed rows are the double kernel's (current_product.hpp,
// finish_current_row) on the widened sum. A row's odd last block pairs with a zero block and
// the zero node (an extra node of the operand, all zero), so a non-finite x never meets a
// padding zero.
//
// A copy may hold its entries in half precision too (`with_half`; multiply_rows with
// PairedPrecision::half), for a K too large for the caches, where the products are bound by
// memory: halves (half_float.hpp) of the float entries, K scaled first by a power
// of two 2^-s that puts its largest diagonal entry (the largest entry of a positive
// semi-definite K) below 2^15; the row's float sum is multiplied back by 2^s, exactly. The
// AVX2 kernel widens them with F16C, the portable one exactly alike.
//
// The copy is symmetric bit for bit (the off-diagonal blocks are their mirrors' transposes in K;
// a diagonal block's lower entries are taken from its upper ones). The product is not exactly
// linear (x and the sums are rounded), so a cycle on it is a symmetric operator to float
// round-off: CG converges on it as on the double cycle (test_current_vcycle), and confirms its
// convergence on the double system (preconditioned_conjugate_gradient's `exact`).
#pragma once

#include "physics/core/executor.hpp"
#include "physics/solve/current_product.hpp"

#include <cstdint>
#include <vector>

namespace incise::physics {

enum class PairedPrecision { single, half };

class PairedBlocks {
 public:
  PairedBlocks() = default;
  // From K's rows (row_start, columns, stiffness of `rows`), `nodes` block rows, filled on
  // `executor`'s threads in one pass over K; `with_half`: the halves too.
  PairedBlocks(const CurrentRows& rows, int nodes, Executor& executor, bool with_half = false);
  // The same into this copy's storage, grown where it is too small, never shrunk: a copy
  // rebuilt every step (CurrentVcycle's) takes no fresh memory, whose pages the system would
  // zero again each time (multi-megabyte at 75k elements).
  void build(const CurrentRows& rows, int nodes, Executor& executor, bool with_half = false);
  // The bytes a single-precision copy of these rows takes (24 floats a pair).
  static std::size_t single_bytes(const CurrentRows& rows, int nodes);

  int nodes() const { return nodes_; }
  bool empty() const { return nodes_ == 0; }
  bool has_half() const { return with_half_; }
  // 2^s of the halves.
  double half_scale() const { return half_scale_; }
  // Floats an operand takes: 4 a node and the zero node's 4.
  std::size_t operand_size() const { return 4 * (static_cast<std::size_t>(nodes_) + 1); }

  // Nodes [begin, end) of `operand` = x rounded to float (x's entries [3 begin, 3 end)), zero on
  // the fixed nodes of `rows`; the 4th float of each node and the zero node stay as the
  // caller zeroed them (an operand is allocated zeroed, operand_size()).
  static void round_operand(const CurrentRows& rows, const double* x, float* operand, int begin, int end);
  // y rows [begin, end) of A x (current_product.hpp's A, the masses, springs, coefficients and
  // fixed rows of `rows`), K's part from this copy's entries in `precision` (half: has_half())
  // and `operand` (x rounded, round_operand).
  void multiply_rows(const CurrentRows& rows, const double* x, const float* operand, double* y, int begin, int end,
                     PairedPrecision precision = PairedPrecision::single) const;
  // Block `index` (0 for the row's first) of block row `row` as the copy holds it in
  // `precision`, widened (and scaled back).
  Mat3 block(int row, int index, PairedPrecision precision = PairedPrecision::single) const;

 private:
  int nodes_ = 0;
  std::vector<int> pair_start_;    // nodes + 1: row r's pairs are [pair_start_[r], pair_start_[r + 1])
  std::vector<int> pair_columns_;  // 2 a pair: the blocks' columns (nodes_, the zero node, for padding)
  bool with_half_ = false;
  double half_scale_ = 1.0;
  // 24 a pair (above), and the same scaled by 1 / half_scale_ in halves (with_half_); both
  // may be longer than the pairs (build()).
  std::vector<float> blocks_;
  std::vector<std::uint16_t> halves_;
};

// Whether PairedBlocks runs its AVX2 + FMA kernel on this CPU (block_product_vectorised() and
// FMA; its bits are the portable kernel's).
bool paired_product_vectorised();

}  // namespace incise::physics
