#include "physics/solve/supernodal_factor.hpp"

#include "physics/solve/block_product.hpp"

#include <Eigen/CholmodSupport>
#include <Eigen/SparseCholesky>

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <string>

namespace incise::physics {

namespace {

void check(bool condition, const std::string& what) {
  if (!condition) throw std::invalid_argument("SupernodalFactor: " + what);
}

// The layout's own checks: the solve reads nothing outside the arrays and only writes later
// columns while it eliminates, which is what makes its two sweeps a triangular solve.
void check_layout(const SupernodalLayout& layout) {
  const int n = layout.size;
  check(n >= 0 && static_cast<int>(layout.permutation.size()) == n, "the permutation needs one entry per row");
  std::vector<char> seen(static_cast<size_t>(n), 0);
  for (const int row : layout.permutation) {
    check(row >= 0 && row < n && !seen[static_cast<size_t>(row)], "the permutation repeats or leaves a row");
    seen[static_cast<size_t>(row)] = 1;
  }
  const size_t supernodes = layout.first_column.empty() ? 0 : layout.first_column.size() - 1;
  check(!layout.first_column.empty() && layout.row_start.size() == supernodes + 1 &&
            layout.value_start.size() == supernodes + 1,
        "first_column, row_start and value_start need one entry per supernode and one more");
  check(layout.first_column.front() == 0 && layout.first_column.back() == n, "the supernodes must cover the columns");
  check(layout.row_start.front() == 0 && layout.row_start.back() == static_cast<int>(layout.row_indices.size()),
        "row_start must cover row_indices");
  check(layout.value_start.front() == 0 && layout.value_start.back() == static_cast<std::int64_t>(layout.values.size()),
        "value_start must cover values");
  for (size_t s = 0; s < supernodes; ++s) {
    const int first = layout.first_column[s], columns = layout.first_column[s + 1] - first;
    const int rows = layout.row_start[s + 1] - layout.row_start[s];
    check(columns > 0 && rows >= columns, "supernode " + std::to_string(s) + " has fewer rows than columns");
    check(layout.value_start[s + 1] - layout.value_start[s] == std::int64_t{rows} * columns,
          "supernode " + std::to_string(s) + "'s block is not rows x columns");
    const int* indices = layout.row_indices.data() + layout.row_start[s];
    for (int j = 0; j < columns; ++j) check(indices[j] == first + j, "supernode " + std::to_string(s) + "'s rows must start with its columns");
    for (int i = columns; i < rows; ++i)
      check(indices[i] > indices[i - 1] && indices[i] < n, "supernode " + std::to_string(s) + "'s rows must increase below it");
  }
}

using SparseMatrix = Eigen::SparseMatrix<double>;

// Eigen's CHOLMOD wrapper, its factor (protected there) in reach.
struct CholmodBuild : Eigen::CholmodSupernodalLLT<SparseMatrix> {
  const cholmod_factor& factor() const { return *m_cholmodFactor; }
};

// CHOLMOD's supernodal LL^T (Eigen's wrapper asks for it and keeps it as it is).
SupernodalFactor read_cholmod(const cholmod_factor& factor, bool single_precision) {
  if (!factor.is_super || !factor.is_ll || factor.itype != CHOLMOD_INT || factor.xtype != CHOLMOD_REAL)
    throw std::runtime_error("SupernodalFactor: CHOLMOD's factor is not the supernodal LL^T of int indices it was asked for");
  const auto supernodes = static_cast<size_t>(factor.nsuper);
  const int* row_start = static_cast<const int*>(factor.pi);
  const int* value_start = static_cast<const int*>(factor.px);
  const std::vector<std::int64_t> value_offsets(value_start, value_start + supernodes + 1);
  SupernodalLayout layout;
  layout.size = static_cast<int>(factor.n);
  layout.permutation = {static_cast<const int*>(factor.Perm), factor.n};
  layout.first_column = {static_cast<const int*>(factor.super), supernodes + 1};
  layout.row_start = {row_start, supernodes + 1};
  layout.row_indices = {static_cast<const int*>(factor.s), static_cast<size_t>(row_start[supernodes])};
  layout.value_start = value_offsets;
  layout.values = {static_cast<const double*>(factor.x), static_cast<size_t>(value_start[supernodes])};
  return SupernodalFactor(layout, single_precision);
}

// Eigen's simplicial LL^T: each column a supernode of one (its diagonal entry first).
SupernodalFactor read_simplicial(const Eigen::SimplicialLLT<SparseMatrix>& simplicial, bool single_precision) {
  const SparseMatrix& lower = simplicial.matrixL().nestedExpression();
  if (!lower.isCompressed()) throw std::runtime_error("SupernodalFactor: the simplicial factor is not compressed");
  const int n = static_cast<int>(lower.cols());
  std::vector<int> permutation(static_cast<size_t>(n)), columns(static_cast<size_t>(n) + 1);
  for (int k = 0; k <= n; ++k) columns[static_cast<size_t>(k)] = k;
  // Eigen solves with z = P b, z[P(i)] = b[i]: row k of the permuted system is P^-1(k).
  const auto& inverse = simplicial.permutationPinv().indices();
  for (int k = 0; k < n; ++k) permutation[static_cast<size_t>(k)] = inverse.size() == n ? inverse[k] : k;
  const std::vector<std::int64_t> value_offsets(lower.outerIndexPtr(), lower.outerIndexPtr() + n + 1);
  SupernodalLayout layout;
  layout.size = n;
  layout.permutation = permutation;
  layout.first_column = columns;
  layout.row_start = {lower.outerIndexPtr(), static_cast<size_t>(n) + 1};
  layout.row_indices = {lower.innerIndexPtr(), static_cast<size_t>(lower.nonZeros())};
  layout.value_start = value_offsets;
  layout.values = {lower.valuePtr(), static_cast<size_t>(lower.nonZeros())};
  return SupernodalFactor(layout, single_precision);
}

}  // namespace

SupernodalFactor SupernodalFactor::with_cholmod(const Eigen::SparseMatrix<double>& lower, bool single_precision) {
  CholmodBuild cholmod;
  cholmod.compute(lower);
  if (cholmod.info() != Eigen::Success) throw std::runtime_error("SupernodalFactor: CHOLMOD found the matrix not positive definite");
  SupernodalFactor factor = read_cholmod(cholmod.factor(), single_precision);
  factor.factor_nonzeros_ = static_cast<std::int64_t>(cholmod.cholmod().lnz);
  return factor;
}

SupernodalFactor SupernodalFactor::with_simplicial(const Eigen::SparseMatrix<double>& lower, bool single_precision) {
  const Eigen::SimplicialLLT<SparseMatrix> simplicial(lower);
  if (simplicial.info() != Eigen::Success) throw std::runtime_error("SupernodalFactor: the matrix is not positive definite");
  SupernodalFactor factor = read_simplicial(simplicial, single_precision);
  factor.factor_nonzeros_ = simplicial.matrixL().nestedExpression().nonZeros();
  return factor;
}

SupernodalFactor::SupernodalFactor(const SupernodalLayout& layout, bool single_precision) {
  check_layout(layout);
  size_ = layout.size;
  permutation_.assign(layout.permutation.begin(), layout.permutation.end());
  first_column_.assign(layout.first_column.begin(), layout.first_column.end());
  row_start_.assign(layout.row_start.begin(), layout.row_start.end());
  row_indices_.assign(layout.row_indices.begin(), layout.row_indices.end());
  value_start_.assign(layout.value_start.begin(), layout.value_start.end());
  if (single_precision) {
    single_values_.resize(layout.values.size());
    std::transform(layout.values.begin(), layout.values.end(), single_values_.begin(),
                   [](double v) { return static_cast<float>(v); });
  } else {
    double_values_.assign(layout.values.begin(), layout.values.end());
  }
  inverse_diagonal_.resize(static_cast<size_t>(size_));
  for (size_t s = 0; s + 1 < first_column_.size(); ++s) {
    const int first = first_column_[s], columns = first_column_[s + 1] - first;
    const int rows = row_start_[s + 1] - row_start_[s];
    tallest_ = std::max(tallest_, rows);
    for (int j = 0; j < columns; ++j) {
      const double diagonal = layout.values[static_cast<size_t>(value_start_[s] + std::int64_t{j} * rows + j)];
      check(diagonal > 0 && std::isfinite(diagonal), "column " + std::to_string(first + j) + "'s diagonal is not positive");
      inverse_diagonal_[static_cast<size_t>(first + j)] = 1.0 / diagonal;
    }
  }
}

namespace {

// The two column kernels, the whole of the solve's arithmetic: `column` times a scalar taken
// from `buffer`, and the dot of `column` with `buffer`, over `count` entries. Both are written
// once and compiled twice, for AVX2 and for the baseline; each entry's operations (and the dot's
// running sums, entry i into sum i mod 16, then folded in halves) are the same in both,
// so the two give the same bits (this file is compiled without contraction into fused
// multiply-adds).
template <typename Scalar>
[[gnu::always_inline]] inline void subtract_column(const Scalar* column, double factor, double* buffer, int count) {
  for (int i = 0; i < count; ++i) buffer[i] -= static_cast<double>(column[i]) * factor;
}

template <typename Scalar>
[[gnu::always_inline]] inline double column_dot(const Scalar* column, const double* buffer, int count) {
  // Sixteen running sums: four vectors of four in AVX2, enough to hide the additions' latency.
  constexpr int lanes = 16;
  double sums[lanes] = {};
  int i = 0;
  for (; i + lanes <= count; i += lanes)
    for (int lane = 0; lane < lanes; ++lane) sums[lane] += static_cast<double>(column[i + lane]) * buffer[i + lane];
  for (int lane = 0; lane < 8; ++lane) sums[lane] += sums[lane + 8];
  for (int lane = 0; lane < 4; ++lane) sums[lane] += sums[lane + 4];
  double sum = (sums[0] + sums[2]) + (sums[1] + sums[3]);
  for (; i < count; ++i) sum += static_cast<double>(column[i]) * buffer[i];
  return sum;
}

// One supernode's block (rows x columns, column-major) against its contiguous buffer (its own
// columns' entries, then its rows below): forward, x_j = buffer_j / L_jj, then the rows after
// j lose L_ij x_j; backward, from the last column, x_j = (buffer_j - sum_(i > j) L_ij x_i) / L_jj.
template <typename Scalar>
[[gnu::always_inline]] inline void forward_block(const Scalar* block, const double* inverse_diagonal, int rows,
                                                 int columns, double* buffer) {
  for (int j = 0; j < columns; ++j) {
    const double xj = buffer[j] * inverse_diagonal[j];
    buffer[j] = xj;
    subtract_column(block + static_cast<std::int64_t>(j) * rows + j + 1, xj, buffer + j + 1, rows - j - 1);
  }
}

template <typename Scalar>
[[gnu::always_inline]] inline void backward_block(const Scalar* block, const double* inverse_diagonal, int rows,
                                                  int columns, double* buffer) {
  for (int j = columns; j-- > 0;) {
    const double sum = column_dot(block + static_cast<std::int64_t>(j) * rows + j + 1, buffer + j + 1, rows - j - 1);
    buffer[j] = (buffer[j] - sum) * inverse_diagonal[j];
  }
}

template <typename Scalar>
__attribute__((target("avx2"))) void avx2_forward_block(const Scalar* block, const double* inverse_diagonal, int rows,
                                                        int columns, double* buffer) {
  forward_block(block, inverse_diagonal, rows, columns, buffer);
}
template <typename Scalar>
__attribute__((target("avx2"))) void avx2_backward_block(const Scalar* block, const double* inverse_diagonal, int rows,
                                                         int columns, double* buffer) {
  backward_block(block, inverse_diagonal, rows, columns, buffer);
}
template <typename Scalar>
void portable_forward_block(const Scalar* block, const double* inverse_diagonal, int rows, int columns, double* buffer) {
  forward_block(block, inverse_diagonal, rows, columns, buffer);
}
template <typename Scalar>
void portable_backward_block(const Scalar* block, const double* inverse_diagonal, int rows, int columns,
                             double* buffer) {
  backward_block(block, inverse_diagonal, rows, columns, buffer);
}

}  // namespace

template <typename Scalar>
void SupernodalFactor::forward(const Scalar* values, double* z, double* buffer) const {
  const bool vectorised = block_product_vectorised();
  const size_t supernodes = first_column_.size() - 1;
  for (size_t s = 0; s < supernodes; ++s) {
    const int first = first_column_[s], columns = first_column_[s + 1] - first;
    const int rows = row_start_[s + 1] - row_start_[s];
    const int* indices = row_indices_.data() + row_start_[s];
    // The rows below start from zero and are subtracted from z after: the scatter's sums do
    // not depend on the order supernodes share rows in.
    std::copy(z + first, z + first + columns, buffer);
    std::fill(buffer + columns, buffer + rows, 0.0);
    const Scalar* block = values + value_start_[s];
    const double* inverse = inverse_diagonal_.data() + first;
    if (vectorised)
      avx2_forward_block(block, inverse, rows, columns, buffer);
    else
      portable_forward_block(block, inverse, rows, columns, buffer);
    std::copy(buffer, buffer + columns, z + first);
    for (int i = columns; i < rows; ++i) z[indices[i]] += buffer[i];
  }
}

template <typename Scalar>
void SupernodalFactor::backward(const Scalar* values, double* z, double* buffer) const {
  const bool vectorised = block_product_vectorised();
  for (size_t s = first_column_.size() - 1; s-- > 0;) {
    const int first = first_column_[s], columns = first_column_[s + 1] - first;
    const int rows = row_start_[s + 1] - row_start_[s];
    const int* indices = row_indices_.data() + row_start_[s];
    for (int i = 0; i < rows; ++i) buffer[i] = z[indices[i]];  // its own columns first
    const Scalar* block = values + value_start_[s];
    const double* inverse = inverse_diagonal_.data() + first;
    if (vectorised)
      avx2_backward_block(block, inverse, rows, columns, buffer);
    else
      portable_backward_block(block, inverse, rows, columns, buffer);
    std::copy(buffer, buffer + columns, z + first);
  }
}

void SupernodalFactor::solve(double* x, std::vector<double>& work) const {
  work.resize(static_cast<size_t>(size_) + static_cast<size_t>(tallest_));
  double* z = work.data();
  double* below = z + size_;
  for (int k = 0; k < size_; ++k) z[k] = x[permutation_[static_cast<size_t>(k)]];
  if (!single_values_.empty()) {
    forward(single_values_.data(), z, below);
    backward(single_values_.data(), z, below);
  } else {
    forward(double_values_.data(), z, below);
    backward(double_values_.data(), z, below);
  }
  for (int k = 0; k < size_; ++k) x[permutation_[static_cast<size_t>(k)]] = z[k];
}

}  // namespace incise::physics
