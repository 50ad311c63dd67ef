#include "physics/solve/paired_blocks.hpp"

#include "physics/core/cpu_features.hpp"
#include "physics/solve/block_product.hpp"
#include "physics/solve/half_float.hpp"

#include <algorithm>
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

template <typename Storage>
struct PairedView {
  const int* pair_start;
  const int* pair_columns;
  const Storage* blocks;
  double scale;
};

// K's block k as rows of 4 floats at out[0], out[8], out[16] (the 4th zero): the rows of the
// column-major block rounded, a diagonal block's lower entries from its upper ones (the copy
// symmetric bit for bit).
void round_block(const double* b, bool diagonal, float* out) {
  for (int i = 0; i < 3; ++i) {
    float* row = out + 8 * i;
    for (int j = 0; j < 3; ++j) row[j] = static_cast<float>(diagonal && i > j ? b[j + 3 * i] : b[i + 3 * j]);
    row[3] = 0.0f;
  }
}

// The lanes' sum in the kernels' order.
float lane_sum(const float lanes[8]) {
  return ((lanes[0] + lanes[4]) + (lanes[1] + lanes[5])) + ((lanes[2] + lanes[6]) + (lanes[3] + lanes[7]));
}

float widen(float entry) { return entry; }
float widen(std::uint16_t entry) { return half_to_float(entry); }

template <typename Storage>
void portable_rows(const CurrentRows& rows, const PairedView<Storage>& paired, const double* x, const float* operand,
                   double* y, int begin, int end) {
  for (int row = begin; row < end; ++row) {
    if (copy_fixed_row(rows, x, y, row)) continue;
    float lanes[3][8] = {};
    for (int pair = paired.pair_start[row]; pair < paired.pair_start[row + 1]; ++pair) {
      const Storage* b = paired.blocks + pair_floats * static_cast<std::size_t>(pair);
      const float* v = operand + 4 * static_cast<std::size_t>(paired.pair_columns[2 * pair]);
      const float* w = operand + 4 * static_cast<std::size_t>(paired.pair_columns[2 * pair + 1]);
      for (int i = 0; i < 3; ++i)
        for (int l = 0; l < 8; ++l) lanes[i][l] = std::fma(widen(b[8 * i + l]), l < 4 ? v[l] : w[l - 4], lanes[i][l]);
    }
    double sum[3];
    for (int i = 0; i < 3; ++i) sum[i] = paired.scale * static_cast<double>(lane_sum(lanes[i]));
    finish_current_row(rows, x, y, row, sum);
  }
}

#if defined(INCISE_PAIRED_PRODUCT_AVX2)
__attribute__((target("avx2,fma,f16c"))) inline __m256 load_row(const float* b) { return _mm256_loadu_ps(b); }
__attribute__((target("avx2,fma,f16c"))) inline __m256 load_row(const std::uint16_t* b) {
  return _mm256_cvtph_ps(_mm_loadu_si128(reinterpret_cast<const __m128i*>(b)));
}

template <typename Storage>
__attribute__((target("avx2,fma,f16c"))) void avx2_rows(const CurrentRows& rows, const PairedView<Storage>& paired,
                                                        const double* x, const float* operand, double* y, int begin,
                                                        int end) {
  for (int row = begin; row < end; ++row) {
    if (copy_fixed_row(rows, x, y, row)) continue;
    __m256 a0 = _mm256_setzero_ps(), a1 = a0, a2 = a0;
    for (int pair = paired.pair_start[row]; pair < paired.pair_start[row + 1]; ++pair) {
      const Storage* b = paired.blocks + pair_floats * static_cast<std::size_t>(pair);
      const __m256 v = _mm256_insertf128_ps(
          _mm256_castps128_ps256(_mm_loadu_ps(operand + 4 * static_cast<std::size_t>(paired.pair_columns[2 * pair]))),
          _mm_loadu_ps(operand + 4 * static_cast<std::size_t>(paired.pair_columns[2 * pair + 1])), 1);
      a0 = _mm256_fmadd_ps(load_row(b), v, a0);
      a1 = _mm256_fmadd_ps(load_row(b + 8), v, a1);
      a2 = _mm256_fmadd_ps(load_row(b + 16), v, a2);
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
    double sum[3];
    for (int i = 0; i < 3; ++i) sum[i] = paired.scale * static_cast<double>(out[i]);
    finish_current_row(rows, x, y, row, sum);
  }
}
#endif

template <typename Storage>
void rows_product(const CurrentRows& rows, const PairedView<Storage>& paired, bool vectorised, const double* x,
                  const float* operand, double* y, int begin, int end) {
#if defined(INCISE_PAIRED_PRODUCT_AVX2)
  if (vectorised) return avx2_rows(rows, paired, x, operand, y, begin, end);
#endif
  (void)vectorised;
  portable_rows(rows, paired, x, operand, y, begin, end);
}

// The largest diagonal entry of K's diagonal blocks (at least that of any entry for a positive
// semi-definite K).
double largest_diagonal(const CurrentRows& rows, int nodes) {
  double largest = 0;
  for (int row = 0; row < nodes; ++row) {
    const int* found = std::lower_bound(rows.columns + rows.row_start[row], rows.columns + rows.row_start[row + 1], row);
    if (found == rows.columns + rows.row_start[row + 1] || *found != row) continue;
    const double* b = rows.stiffness + 9 * static_cast<std::size_t>(found - rows.columns);
    largest = std::max({largest, std::abs(b[0]), std::abs(b[4]), std::abs(b[8])});
  }
  return largest;
}

}  // namespace

bool paired_product_vectorised() {
#if defined(INCISE_PAIRED_PRODUCT_AVX2)
  return block_product_vectorised() && cpu_has_fma() && cpu_has_f16c();
#else
  return false;
#endif
}

std::size_t PairedBlocks::single_bytes(const CurrentRows& rows, int nodes) {
  std::size_t pairs = 0;
  for (int row = 0; row < nodes; ++row) pairs += static_cast<std::size_t>(rows.row_start[row + 1] - rows.row_start[row] + 1) / 2;
  return pairs * pair_floats * sizeof(float);
}

PairedBlocks::PairedBlocks(const CurrentRows& rows, int nodes, Executor& executor, bool with_half) {
  build(rows, nodes, executor, with_half);
}

void PairedBlocks::build(const CurrentRows& rows, int nodes, Executor& executor, bool with_half) {
  nodes_ = nodes;
  with_half_ = with_half;
  pair_start_.resize(static_cast<std::size_t>(nodes) + 1);
  pair_start_[0] = 0;
  for (int row = 0; row < nodes; ++row)
    pair_start_[static_cast<std::size_t>(row) + 1] =
        pair_start_[static_cast<std::size_t>(row)] + (rows.row_start[row + 1] - rows.row_start[row] + 1) / 2;
  const std::size_t pairs = static_cast<std::size_t>(pair_start_.back());
  const auto grow = [](auto& storage, std::size_t size) {
    if (storage.size() < size) storage.resize(size);
  };
  grow(pair_columns_, 2 * pairs);
  grow(blocks_, pair_floats * pairs);
  float inverse_scale = 1.0f;
  half_scale_ = 1.0;
  if (with_half) {
    const double largest = largest_diagonal(rows, nodes);
    const int exponent = largest > 0 && std::isfinite(largest) ? std::ilogb(largest) - 14 : 0;
    half_scale_ = std::ldexp(1.0, exponent);
    inverse_scale = std::ldexp(1.0f, -exponent);
    grow(halves_, pair_floats * pairs);
  }
  executor.parallel_for(nodes, [&](int begin, int end) {
    float scaled[pair_floats];
    for (int row = begin; row < end; ++row) {
      const int first = rows.row_start[row], stop = rows.row_start[row + 1];
      const std::size_t row_pairs = static_cast<std::size_t>(pair_start_[static_cast<std::size_t>(row)]);
      for (int k = first; k < stop; ++k) {
        const std::size_t pair = row_pairs + static_cast<std::size_t>(k - first) / 2, side = static_cast<std::size_t>(k - first) % 2;
        pair_columns_[2 * pair + side] = rows.columns[k];
        round_block(rows.stiffness + 9 * static_cast<std::size_t>(k), rows.columns[k] == row,
                    blocks_.data() + pair_floats * pair + 4 * side);
      }
      if ((stop - first) % 2 != 0) {  // the odd last block's partner: zero, on the zero node
        const std::size_t pair = row_pairs + static_cast<std::size_t>(stop - first) / 2;
        pair_columns_[2 * pair + 1] = nodes_;
        for (int i = 0; i < 3; ++i) std::fill_n(blocks_.data() + pair_floats * pair + 8 * i + 4, 4, 0.0f);
      }
      if (!with_half) continue;
      // Scaled by a power of two in float: exact (K's entries are far above float's
      // subnormals), then rounded to half.
      for (int pair = pair_start_[static_cast<std::size_t>(row)]; pair < pair_start_[static_cast<std::size_t>(row) + 1]; ++pair) {
        const std::size_t at = pair_floats * static_cast<std::size_t>(pair);
        for (std::size_t i = 0; i < pair_floats; ++i) scaled[i] = blocks_[at + i] * inverse_scale;
        floats_to_halves(scaled, halves_.data() + at, pair_floats);
      }
    }
  }, rows_per_thread);
}

void PairedBlocks::round_operand(const CurrentRows& rows, const double* x, float* operand, int begin, int end) {
  for (int node = begin; node < end; ++node) {
    const bool fixed = is_fixed_row(rows, node);
    for (int i = 0; i < 3; ++i)
      operand[4 * static_cast<std::size_t>(node) + static_cast<std::size_t>(i)] =
          fixed ? 0.0f : static_cast<float>(x[3 * static_cast<std::size_t>(node) + static_cast<std::size_t>(i)]);
  }
}

Mat3 PairedBlocks::block(int row, int index, PairedPrecision precision) const {
  const std::size_t at = pair_floats * static_cast<std::size_t>(pair_start_[static_cast<std::size_t>(row)] + index / 2) +
                         4 * static_cast<std::size_t>(index % 2);
  Mat3 out;
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j) {
      const std::size_t entry = at + 8 * static_cast<std::size_t>(i) + static_cast<std::size_t>(j);
      out(i, j) = precision == PairedPrecision::half ? half_scale_ * static_cast<double>(half_to_float(halves_[entry]))
                                                     : static_cast<double>(blocks_[entry]);
    }
  return out;
}

void PairedBlocks::multiply_rows(const CurrentRows& rows, const double* x, const float* operand, double* y, int begin,
                                 int end, PairedPrecision precision) const {
  const bool vectorised = paired_product_vectorised();
  if (precision == PairedPrecision::half)
    return rows_product(rows, PairedView<std::uint16_t>{pair_start_.data(), pair_columns_.data(), halves_.data(), half_scale_},
                        vectorised, x, operand, y, begin, end);
  rows_product(rows, PairedView<float>{pair_start_.data(), pair_columns_.data(), blocks_.data(), 1.0}, vectorised, x,
               operand, y, begin, end);
}

}  // namespace incise::physics
