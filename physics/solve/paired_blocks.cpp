#include "physics/solve/paired_blocks.hpp"

#include "physics/core/cpu_features.hpp"
#include "physics/solve/block_product.hpp"

#include <cmath>
#include <cstddef>

#if defined(__x86_64__) && (defined(__GNUC__) || defined(__clang__))
#define INCISE_PAIRED_PRODUCT_AVX2 1
#include <immintrin.h>
#endif

namespace incise::physics {

namespace {

constexpr int rows_per_thread = 256;  // as CurrentSystem::multiply
constexpr std::size_t pair_floats = 24;

bool is_fixed(const CurrentRows& rows, int node) { return rows.fixed && rows.fixed[node] != 0; }

// Row i of K's block k, rounded, into out[0..2]; a diagonal block's lower entries from its upper
// ones (the copy symmetric bit for bit).
void round_block_row(const CurrentRows& rows, int k, bool diagonal, int i, float* out) {
  const double* b = rows.stiffness + 9 * static_cast<std::size_t>(k);  // column-major
  for (int j = 0; j < 3; ++j) out[j] = static_cast<float>(diagonal && i > j ? b[j + 3 * i] : b[i + 3 * j]);
}

// The lanes' sum in the kernels' order.
float lane_sum(const float lanes[8]) {
  return ((lanes[0] + lanes[4]) + (lanes[1] + lanes[5])) + ((lanes[2] + lanes[6]) + (lanes[3] + lanes[7]));
}

void portable_rows(const CurrentRows& rows, const int* pair_start, const int* pair_columns, const float* blocks,
                   const double* x, const float* operand, double* y, int begin, int end) {
  for (int row = begin; row < end; ++row) {
    const std::size_t offset = 3 * static_cast<std::size_t>(row);
    if (is_fixed(rows, row)) {
      for (int i = 0; i < 3; ++i) y[offset + i] = x[offset + i];
      continue;
    }
    float lanes[3][8] = {};
    for (int pair = pair_start[row]; pair < pair_start[row + 1]; ++pair) {
      const float* b = blocks + pair_floats * static_cast<std::size_t>(pair);
      const float* v = operand + 4 * static_cast<std::size_t>(pair_columns[2 * pair]);
      const float* w = operand + 4 * static_cast<std::size_t>(pair_columns[2 * pair + 1]);
      for (int i = 0; i < 3; ++i)
        for (int l = 0; l < 8; ++l) lanes[i][l] = std::fma(b[8 * i + l], l < 4 ? v[l] : w[l - 4], lanes[i][l]);
    }
    double sum[3] = {lane_sum(lanes[0]), lane_sum(lanes[1]), lane_sum(lanes[2])};
    finish_current_row(rows, x, y, row, sum);
  }
}

#if defined(INCISE_PAIRED_PRODUCT_AVX2)
__attribute__((target("avx2,fma"))) void avx2_rows(const CurrentRows& rows, const int* pair_start, const int* pair_columns,
                                                   const float* blocks, const double* x, const float* operand, double* y,
                                                   int begin, int end) {
  for (int row = begin; row < end; ++row) {
    const std::size_t offset = 3 * static_cast<std::size_t>(row);
    if (is_fixed(rows, row)) {
      for (int i = 0; i < 3; ++i) y[offset + i] = x[offset + i];
      continue;
    }
    __m256 a0 = _mm256_setzero_ps(), a1 = a0, a2 = a0;
    for (int pair = pair_start[row]; pair < pair_start[row + 1]; ++pair) {
      const float* b = blocks + pair_floats * static_cast<std::size_t>(pair);
      const __m256 v = _mm256_insertf128_ps(
          _mm256_castps128_ps256(_mm_loadu_ps(operand + 4 * static_cast<std::size_t>(pair_columns[2 * pair]))),
          _mm_loadu_ps(operand + 4 * static_cast<std::size_t>(pair_columns[2 * pair + 1])), 1);
      a0 = _mm256_fmadd_ps(_mm256_loadu_ps(b), v, a0);
      a1 = _mm256_fmadd_ps(_mm256_loadu_ps(b + 8), v, a1);
      a2 = _mm256_fmadd_ps(_mm256_loadu_ps(b + 16), v, a2);
    }
    // Per row i: the halves' lanes added (l0 + l4, ..), then the pairs of those, then the two
    // pair sums: lane_sum's order.
    const __m128 h0 = _mm_add_ps(_mm256_castps256_ps128(a0), _mm256_extractf128_ps(a0, 1));
    const __m128 h1 = _mm_add_ps(_mm256_castps256_ps128(a1), _mm256_extractf128_ps(a1, 1));
    const __m128 h2 = _mm_add_ps(_mm256_castps256_ps128(a2), _mm256_extractf128_ps(a2, 1));
    // hadd(h0, h1) = (h0_0 + h0_1, h0_2 + h0_3, h1_0 + h1_1, h1_2 + h1_3)
    const __m128 sums = _mm_hadd_ps(_mm_hadd_ps(h0, h1), _mm_hadd_ps(h2, h2));
    alignas(16) float out[4];
    _mm_store_ps(out, sums);
    double sum[3] = {out[0], out[1], out[2]};
    finish_current_row(rows, x, y, row, sum);
  }
}
#endif

}  // namespace

bool paired_product_vectorised() {
#if defined(INCISE_PAIRED_PRODUCT_AVX2)
  return block_product_vectorised() && cpu_has_fma();
#else
  return false;
#endif
}

PairedBlocks::PairedBlocks(const CurrentRows& rows, int nodes, Executor& executor) : nodes_(nodes) {
  pair_start_.resize(static_cast<std::size_t>(nodes) + 1);
  pair_start_[0] = 0;
  for (int row = 0; row < nodes; ++row)
    pair_start_[static_cast<std::size_t>(row) + 1] =
        pair_start_[static_cast<std::size_t>(row)] + (rows.row_start[row + 1] - rows.row_start[row] + 1) / 2;
  const std::size_t pairs = static_cast<std::size_t>(pair_start_.back());
  pair_columns_.resize(2 * pairs);
  blocks_.resize(pair_floats * pairs);
  executor.parallel_for(nodes, [&](int begin, int end) {
    for (int row = begin; row < end; ++row) {
      const int first = rows.row_start[row], stop = rows.row_start[row + 1];
      for (int pair = pair_start_[static_cast<std::size_t>(row)]; pair < pair_start_[static_cast<std::size_t>(row) + 1]; ++pair) {
        float* b = blocks_.data() + pair_floats * static_cast<std::size_t>(pair);
        for (int half = 0; half < 2; ++half) {
          const int k = first + 2 * (pair - pair_start_[static_cast<std::size_t>(row)]) + half;
          const bool present = k < stop;
          pair_columns_[2 * static_cast<std::size_t>(pair) + static_cast<std::size_t>(half)] = present ? rows.columns[k] : nodes_;
          for (int i = 0; i < 3; ++i) {
            float* lane = b + 8 * i + 4 * half;
            lane[0] = lane[1] = lane[2] = lane[3] = 0.0f;
            if (present) round_block_row(rows, k, rows.columns[k] == row, i, lane);
          }
        }
      }
    }
  }, rows_per_thread);
}

void PairedBlocks::round_operand(const CurrentRows& rows, const double* x, float* operand, int begin, int end) {
  for (int node = begin; node < end; ++node) {
    const bool fixed = is_fixed(rows, node);
    for (int i = 0; i < 3; ++i)
      operand[4 * static_cast<std::size_t>(node) + static_cast<std::size_t>(i)] =
          fixed ? 0.0f : static_cast<float>(x[3 * static_cast<std::size_t>(node) + static_cast<std::size_t>(i)]);
  }
}

Mat3 PairedBlocks::block(int row, int index) const {
  const float* b = blocks_.data() + pair_floats * static_cast<std::size_t>(pair_start_[static_cast<std::size_t>(row)] + index / 2) +
                   4 * static_cast<std::size_t>(index % 2);
  Mat3 out;
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j) out(i, j) = b[8 * i + j];
  return out;
}

void PairedBlocks::multiply_rows(const CurrentRows& rows, const double* x, const float* operand, double* y, int begin,
                                 int end) const {
#if defined(INCISE_PAIRED_PRODUCT_AVX2)
  if (paired_product_vectorised())
    return avx2_rows(rows, pair_start_.data(), pair_columns_.data(), blocks_.data(), x, operand, y, begin, end);
#endif
  portable_rows(rows, pair_start_.data(), pair_columns_.data(), blocks_.data(), x, operand, y, begin, end);
}

}  // namespace incise::physics
