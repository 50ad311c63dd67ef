// The row kernel of the assembled current system's product (current_system.hpp): for rows
// [begin, end) of the stiffness K (block CSR, Eigen's column-major 3x3 blocks, read in place),
//   y_row = x_row                                              on a fixed row,
//   y_row = (c_m m_row) x_row + c_k (sum_k K_k x_col(k) + S_row x_row)   otherwise,
// S_row the row's springs. The sum runs over every block of the row, fixed columns included,
// so x must be zero on the fixed nodes: a finite block times a zero adds a signed zero, which
// leaves a sum that starts at +0 unchanged (it is never -0), so the result has the bits of the
// sum that skips those columns.
//
// Each block product is rounded in the order Eigen's `sum += Matrix3d * x.segment<3>()`
// compiles to on x86-64 (block_product.hpp): rows 0 and 1 (b_i0 x0 + b_i1 x1) + b_i2 x2, row 2
// (b_21 x1 + b_22 x2) + b_20 x0; the finish as `(c_m * m) * x + c_k * sum`. The AVX2 kernel
// (three rows in one 256-bit lane set, the row-2 order by two blends) and the portable one
// give the same bits, those of CurrentSystem's Eigen product before this kernel.
//
// The V-cycle's products in float run on another layout of K (paired_blocks.hpp), this file's
// finish_current_row after them.
#pragma once

#include "physics/solve/block_matrix.hpp"

#include <cstddef>
#include <cstdint>

namespace incise::physics {

struct CurrentRows {
  int blocks = 0;  // K's block count (the last block is loaded with care: nothing after it)
  const int* row_start = nullptr;
  const int* columns = nullptr;
  const double* stiffness = nullptr;  // K's blocks, 9 doubles each, column-major (Mat3)
  const double* masses = nullptr;
  const std::uint8_t* fixed = nullptr;  // null: nothing fixed
  const double* springs = nullptr;      // per node the springs' Mat3 sum; null: no springs
  double mass_coefficient = 0, stiffness_coefficient = 0;
};

inline bool is_fixed_row(const CurrentRows& rows, int row) { return rows.fixed && rows.fixed[row] != 0; }

// A fixed row's y = x, bit for bit (true); false on a free row, left to the caller.
inline bool copy_fixed_row(const CurrentRows& rows, const double* x, double* y, int row) {
  if (!is_fixed_row(rows, row)) return false;
  const std::size_t offset = 3 * static_cast<std::size_t>(row);
  for (std::size_t i = 0; i < 3; ++i) y[offset + i] = x[offset + i];
  return true;
}

// y rows [begin, end) of A x; `free_x` is x zeroed on the fixed nodes (x itself when it is).
void current_rows_product(const CurrentRows& rows, const double* x, const double* free_x, double* y, int begin, int end);

// sum += B v, B column-major, in Eigen's order. Inline, as finish_current_row, for the kernels'
// row loops; their files are compiled without contraction into fused multiply-adds
// (solve.cmake), so every caller rounds alike.
inline void add_block_product(const double* b, const double* v, double sum[3]) {
  const double x0 = v[0], x1 = v[1], x2 = v[2];
  sum[0] += (b[0] * x0 + b[3] * x1) + b[6] * x2;
  sum[1] += (b[1] * x0 + b[4] * x1) + b[7] * x2;
  sum[2] += (b[5] * x1 + b[8] * x2) + b[2] * x0;
}

// A free row's y from its stiffness sum (K's blocks times x, in `sum`, which gains the springs'
// product): y_row = (c_m m_row) x_row + c_k (sum + S_row x_row), in the kernels' order; for a
// kernel that sums K's part its own way (paired_blocks.hpp).
inline void finish_current_row(const CurrentRows& rows, const double* x, double* y, int row, double sum[3]) {
  const std::size_t offset = 3 * static_cast<std::size_t>(row);
  if (rows.springs) add_block_product(rows.springs + 9 * static_cast<std::size_t>(row), x + offset, sum);
  const double mass = rows.mass_coefficient * rows.masses[row];
  for (int i = 0; i < 3; ++i) y[offset + i] = mass * x[offset + i] + rows.stiffness_coefficient * sum[i];
}

}  // namespace incise::physics
