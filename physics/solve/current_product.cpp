#include "physics/solve/current_product.hpp"

#include "physics/solve/block_product.hpp"

#include <cstddef>

#if defined(__x86_64__) && (defined(__GNUC__) || defined(__clang__))
#define INCISE_CURRENT_PRODUCT_AVX2 1
#include <immintrin.h>
#endif

namespace incise::physics {

namespace {

void portable_current_rows(const CurrentRows& rows, const double* stiffness, const double* x, const double* free_x,
                           double* y, int begin, int end) {
  for (int row = begin; row < end; ++row) {
    if (copy_fixed_row(rows, x, y, row)) continue;
    double sum[3] = {0, 0, 0};
    for (int k = rows.row_start[row]; k < rows.row_start[row + 1]; ++k)
      add_block_product(stiffness + 9 * static_cast<std::size_t>(k), free_x + 3 * static_cast<std::size_t>(rows.columns[k]),
                        sum);
    finish_current_row(rows, x, y, row, sum);
  }
}

#if defined(INCISE_CURRENT_PRODUCT_AVX2)
// A column of a block and the entry after it; `masked`: the column alone (lane 3 zero), for
// the block at the end of its array.
template <bool masked>
__attribute__((target("avx2"))) inline __m256d load_column(const double* b) {
  return masked ? _mm256_maskload_pd(b, _mm256_set_epi64x(0, -1, -1, -1)) : _mm256_loadu_pd(b);
}

// B v in Eigen's order, B column-major at b: column j's load (lanes b_0j b_1j b_2j and the
// entry after them, multiplied, never stored) times v_j gives a, m, c; then lanes 0-1 are
// (a + m) + c and lane 2 (c + m) + a, by two blends. `masked` stops the third column's load
// at the block's end (K's last block, nothing after it; a spring block); elsewhere it reads
// the next block's first entry.
template <bool masked>
__attribute__((target("avx2"))) inline __m256d block_product(const double* b, const double* v) {
  const __m256d a = _mm256_mul_pd(load_column<false>(b), _mm256_broadcast_sd(v));
  const __m256d m = _mm256_mul_pd(load_column<false>(b + 3), _mm256_broadcast_sd(v + 1));
  const __m256d c = _mm256_mul_pd(load_column<masked>(b + 6), _mm256_broadcast_sd(v + 2));
  return _mm256_add_pd(_mm256_add_pd(_mm256_blend_pd(a, c, 0b0100), m), _mm256_blend_pd(c, a, 0b0100));
}

// sum += the blocks [k, stop) times free_x (the last of K's blocks masked).
__attribute__((target("avx2"))) inline __m256d add_blocks(const CurrentRows& rows, const double* stiffness,
                                                          const double* free_x, int k, int stop, __m256d sum) {
  const int unmasked = stop < rows.blocks ? stop : stop - 1;
  for (; k < unmasked; ++k)
    sum = _mm256_add_pd(sum, block_product<false>(stiffness + 9 * static_cast<std::size_t>(k),
                                                  free_x + 3 * static_cast<std::size_t>(rows.columns[k])));
  if (k < stop)
    sum = _mm256_add_pd(sum, block_product<true>(stiffness + 9 * static_cast<std::size_t>(k),
                                                 free_x + 3 * static_cast<std::size_t>(rows.columns[k])));
  return sum;
}

// A free row's springs and mass on its block sum, stored.
__attribute__((target("avx2"))) inline void finish_row(const CurrentRows& rows, const double* x, double* y, int row,
                                                       __m256d sum) {
  const __m256i three = _mm256_set_epi64x(0, -1, -1, -1);  // y's row: 3 doubles, never a 4th
  const double* x_row = x + 3 * static_cast<std::size_t>(row);
  if (rows.springs) sum = _mm256_add_pd(sum, block_product<true>(rows.springs + 9 * static_cast<std::size_t>(row), x_row));
  const __m256d mass = _mm256_set1_pd(rows.mass_coefficient * rows.masses[row]);
  _mm256_maskstore_pd(y + 3 * static_cast<std::size_t>(row), three,
                      _mm256_add_pd(_mm256_mul_pd(mass, _mm256_maskload_pd(x_row, three)),
                                    _mm256_mul_pd(_mm256_set1_pd(rows.stiffness_coefficient), sum)));
}

__attribute__((target("avx2"))) void avx2_current_rows(const CurrentRows& rows, const double* stiffness, const double* x,
                                                       const double* free_x, double* y, int begin, int end) {
  const __m256i three = _mm256_set_epi64x(0, -1, -1, -1);
  for (int row = begin; row < end; ++row) {
    if (is_fixed_row(rows, row)) {
      const std::size_t offset = 3 * static_cast<std::size_t>(row);
      _mm256_maskstore_pd(y + offset, three, _mm256_maskload_pd(x + offset, three));
      continue;
    }
    finish_row(rows, x, y, row,
               add_blocks(rows, stiffness, free_x, rows.row_start[row], rows.row_start[row + 1], _mm256_setzero_pd()));
  }
}
#endif

}  // namespace

void current_rows_product(const CurrentRows& rows, const double* x, const double* free_x, double* y, int begin, int end) {
#if defined(INCISE_CURRENT_PRODUCT_AVX2)
  // The block product's switch (tests force the portable kernel through it).
  if (block_product_vectorised()) return avx2_current_rows(rows, rows.stiffness, x, free_x, y, begin, end);
#endif
  portable_current_rows(rows, rows.stiffness, x, free_x, y, begin, end);
}

}  // namespace incise::physics
