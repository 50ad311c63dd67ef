#include "physics/solve/block_product.hpp"

#include "physics/core/cpu_features.hpp"

#include <atomic>

#if defined(__x86_64__) && (defined(__GNUC__) || defined(__clang__))
#define INCISE_BLOCK_PRODUCT_AVX2 1
#include <immintrin.h>
#endif

namespace incise::physics {

namespace {

// The portable kernel: the same operations in the same order as the AVX2 one, lane by lane
// (block_product.hpp). This file is compiled without contraction into fused multiply-adds.
template <typename Scalar>
void portable_rows(const BlockRows& rows, const Scalar* blocks, const double* x, double* y, int begin, int end,
                   bool subtract) {
  for (int row = begin; row < end; ++row) {
    double s0 = 0, s1 = 0, s2 = 0;
    for (int k = rows.row_start[row]; k < rows.row_start[row + 1]; ++k) {
      const Scalar* b = blocks + 9 * static_cast<std::size_t>(k);
      const double* v = x + 3 * static_cast<std::size_t>(rows.columns[k]);
      const double x0 = v[0], x1 = v[1], x2 = v[2];
      s0 += (double(b[0]) * x0 + double(b[3]) * x1) + double(b[6]) * x2;
      s1 += (double(b[1]) * x0 + double(b[4]) * x1) + double(b[7]) * x2;
      s2 += (double(b[2]) * x2 + double(b[5]) * x1) + double(b[8]) * x0;
    }
    double* out = y + 3 * static_cast<std::size_t>(row);
    if (subtract) {
      out[0] -= s0;
      out[1] -= s1;
      out[2] -= s2;
    } else {
      out[0] = s0;
      out[1] = s1;
      out[2] = s2;
    }
  }
}

#if defined(INCISE_BLOCK_PRODUCT_AVX2)
// A column of a block in lane order, widened to double (lane 3 is the next column's first
// entry: multiplied, never stored).
__attribute__((target("avx2"))) inline __m256d load_column(const double* b) { return _mm256_loadu_pd(b); }
__attribute__((target("avx2"))) inline __m256d load_column(const float* b) { return _mm256_cvtps_pd(_mm_loadu_ps(b)); }

template <typename Scalar>
__attribute__((target("avx2"))) void avx2_rows(const BlockRows& rows, const Scalar* blocks, const double* x, double* y,
                                               int begin, int end, bool subtract) {
  const __m256i three = _mm256_set_epi64x(0, -1, -1, -1);  // x's node and y's row: 3 doubles, never a 4th
  for (int row = begin; row < end; ++row) {
    __m256d sum = _mm256_setzero_pd();
    for (int k = rows.row_start[row]; k < rows.row_start[row + 1]; ++k) {
      const Scalar* b = blocks + 9 * static_cast<std::size_t>(k);
      const __m256d v = _mm256_maskload_pd(x + 3 * static_cast<std::size_t>(rows.columns[k]), three);
      // Lanes 0-1 take x0, x1, x2 in turn; lane 2 takes x2, x1, x0.
      __m256d term = _mm256_mul_pd(load_column(b), _mm256_permute4x64_pd(v, 0xA0));
      term = _mm256_add_pd(term, _mm256_mul_pd(load_column(b + 3), _mm256_permute4x64_pd(v, 0x55)));
      term = _mm256_add_pd(term, _mm256_mul_pd(load_column(b + 6), _mm256_permute4x64_pd(v, 0x0A)));
      sum = _mm256_add_pd(sum, term);
    }
    double* out = y + 3 * static_cast<std::size_t>(row);
    if (subtract) sum = _mm256_sub_pd(_mm256_maskload_pd(out, three), sum);
    _mm256_maskstore_pd(out, three, sum);
  }
}

#endif

std::atomic<bool> vectorised_allowed{true};

template <typename Scalar>
void rows_product(const BlockRows& rows, const Scalar* blocks, const double* x, double* y, int begin, int end,
                  bool subtract) {
#if defined(INCISE_BLOCK_PRODUCT_AVX2)
  if (block_product_vectorised()) return avx2_rows(rows, blocks, x, y, begin, end, subtract);
#endif
  portable_rows(rows, blocks, x, y, begin, end, subtract);
}

}  // namespace

void block_rows_product(const BlockRows& rows, const double* blocks, const double* x, double* y, int begin, int end,
                        bool subtract) {
  rows_product(rows, blocks, x, y, begin, end, subtract);
}

void block_rows_product(const BlockRows& rows, const float* blocks, const double* x, double* y, int begin, int end,
                        bool subtract) {
  rows_product(rows, blocks, x, y, begin, end, subtract);
}

bool block_product_vectorised() {
#if defined(INCISE_BLOCK_PRODUCT_AVX2)
  return vectorised_allowed.load(std::memory_order_relaxed) && cpu_has_avx2();
#else
  return false;
#endif
}

void set_block_product_vectorised(bool allowed) { vectorised_allowed.store(allowed, std::memory_order_relaxed); }

}  // namespace incise::physics
