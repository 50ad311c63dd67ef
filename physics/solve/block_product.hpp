// The row kernel of a block CSR product (block_system.hpp): for rows [begin, end),
//   y_row = sum_k B_k x_col(k)      or, subtracting,   y_row -= sum_k B_k x_col(k),
// each row summed in column order by one caller, every 3x3 block product in one fixed order:
//   rows 0 and 1:  (b_i0 x0 + b_i1 x1) + b_i2 x2
//   row 2:         (b_21 x1 + b_22 x2) + b_20 x0
// the order Eigen's `sum += Matrix3d * x.segment<3>()` compiles to on x86-64 (SSE2: rows 0-1
// in one packet, row 2 reduced from its end), so that the blocks' bits are those of the
// product before this kernel. On a CPU with AVX2 the three rows are one 256-bit lane set,
// which needs the block in "lane order" (below) and saves about a third of the product's
// time: the product is bound by its instructions, not by memory, at 20k elements.
//
// Blocks are stored in lane order, 9 scalars each and one more after the last (the 256-bit
// load of a block's third column reads one past it):
//   b00 b10 b22 | b01 b11 b21 | b02 b12 b20
// so that lane i of column c's load multiplies x's (i = 2: the permuted) component: lanes 0-1
// x0, x1, x2 in turn, lane 2 x2, x1, x0. Float blocks (a single-precision copy of the system)
// are widened to double before they multiply; the sums are double either way.
#pragma once

#include "physics/solve/block_matrix.hpp"

#include <cstddef>
#include <vector>

namespace incise::physics {

// The block in lane order.
template <typename Scalar>
void store_lane_order(const Mat3& block, Scalar* out) {
  const double ordered[9] = {block(0, 0), block(1, 0), block(2, 2), block(0, 1), block(1, 1),
                             block(2, 1), block(0, 2), block(1, 2), block(2, 0)};
  for (int i = 0; i < 9; ++i) out[i] = static_cast<Scalar>(ordered[i]);
}

// The block from lane order, widened to double.
template <typename Scalar>
Mat3 load_lane_order(const Scalar* in) {
  Mat3 block;
  block << in[0], in[3], in[6], in[1], in[4], in[7], in[8], in[5], in[2];
  return block;
}

struct BlockRows {
  const int* row_start = nullptr;
  const int* columns = nullptr;
};

// y rows [begin, end) = (or -=, `subtract`) the blocks' product with x. x and y distinct.
void block_rows_product(const BlockRows& rows, const double* blocks, const double* x, double* y, int begin, int end,
                        bool subtract);
void block_rows_product(const BlockRows& rows, const float* blocks, const double* x, double* y, int begin, int end,
                        bool subtract);

// Whether block_rows_product runs its AVX2 kernel on this CPU (its bits are the portable one's).
bool block_product_vectorised();
// Tests: force the portable kernel (false) or the CPU's best (true).
void set_block_product_vectorised(bool allowed);

}  // namespace incise::physics
