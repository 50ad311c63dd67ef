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
SupernodalFactor read_cholmod(const cholmod_factor& factor, bool single_precision, std::int64_t minimum_part_work) {
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
  return SupernodalFactor(layout, single_precision, minimum_part_work);
}

// Eigen's simplicial LL^T: each column a supernode of one (its diagonal entry first).
SupernodalFactor read_simplicial(const Eigen::SimplicialLLT<SparseMatrix>& simplicial, bool single_precision,
                                 std::int64_t minimum_part_work) {
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
  return SupernodalFactor(layout, single_precision, minimum_part_work);
}

}  // namespace

SupernodalFactor SupernodalFactor::with_cholmod(const Eigen::SparseMatrix<double>& lower, bool single_precision,
                                                std::int64_t minimum_part_work) {
  CholmodBuild cholmod;
  cholmod.compute(lower);
  if (cholmod.info() != Eigen::Success) throw std::runtime_error("SupernodalFactor: CHOLMOD found the matrix not positive definite");
  SupernodalFactor factor = read_cholmod(cholmod.factor(), single_precision, minimum_part_work);
  factor.factor_nonzeros_ = static_cast<std::int64_t>(cholmod.cholmod().lnz);
  return factor;
}

SupernodalFactor SupernodalFactor::with_simplicial(const Eigen::SparseMatrix<double>& lower, bool single_precision,
                                                   std::int64_t minimum_part_work) {
  const Eigen::SimplicialLLT<SparseMatrix> simplicial(lower);
  if (simplicial.info() != Eigen::Success) throw std::runtime_error("SupernodalFactor: the matrix is not positive definite");
  SupernodalFactor factor = read_simplicial(simplicial, single_precision, minimum_part_work);
  factor.factor_nonzeros_ = simplicial.matrixL().nestedExpression().nonZeros();
  return factor;
}

SupernodalFactor::SupernodalFactor(const SupernodalLayout& layout, bool single_precision, std::int64_t minimum_part_work) {
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
  split(minimum_part_work);
}

void SupernodalFactor::split(std::int64_t minimum_part_work) {
  const int supernodes = static_cast<int>(first_column_.size()) - 1;
  std::vector<int> supernode_of(static_cast<size_t>(size_));
  for (int s = 0; s < supernodes; ++s)
    std::fill(supernode_of.begin() + first_column_[static_cast<size_t>(s)],
              supernode_of.begin() + first_column_[static_cast<size_t>(s) + 1], s);
  // The tree: a supernode's parent holds its first row below (rows below are ancestors only,
  // numbered after it, so children come first), its subtree's work summed upwards.
  std::vector<int> parent(static_cast<size_t>(supernodes), -1);
  std::vector<std::vector<int>> children(static_cast<size_t>(supernodes));
  std::vector<std::int64_t> work(static_cast<size_t>(supernodes));
  std::vector<int> roots;
  for (int s = 0; s < supernodes; ++s) {
    const int columns = first_column_[static_cast<size_t>(s) + 1] - first_column_[static_cast<size_t>(s)];
    const int rows = row_start_[static_cast<size_t>(s) + 1] - row_start_[static_cast<size_t>(s)];
    work[static_cast<size_t>(s)] += std::int64_t{rows} * columns;
    if (rows > columns) {
      const int up = supernode_of[static_cast<size_t>(row_indices_[static_cast<size_t>(row_start_[static_cast<size_t>(s)] + columns)])];
      parent[static_cast<size_t>(s)] = up;
      children[static_cast<size_t>(up)].push_back(s);
      work[static_cast<size_t>(up)] += work[static_cast<size_t>(s)];
    } else {
      roots.push_back(s);
    }
  }
  // From the roots down: the heaviest subtree of the frontier goes to the top and its children
  // to the frontier, until the frontier's subtrees, dealt heaviest first to the lighter part,
  // balance within 1/16 of their work (or nothing is left to open).
  std::vector<int> frontier = roots, top;
  std::array<std::vector<int>, 2> part_roots;
  for (;;) {
    std::sort(frontier.begin(), frontier.end(),
              [&](int a, int b) { return work[static_cast<size_t>(a)] != work[static_cast<size_t>(b)] ? work[static_cast<size_t>(a)] > work[static_cast<size_t>(b)] : a < b; });
    std::array<std::int64_t, 2> load{0, 0};
    part_roots = {};
    for (const int s : frontier) {
      const int lighter = load[1] < load[0] ? 1 : 0;
      load[static_cast<size_t>(lighter)] += work[static_cast<size_t>(s)];
      part_roots[static_cast<size_t>(lighter)].push_back(s);
    }
    const std::int64_t total = load[0] + load[1];
    if (frontier.empty() || 16 * std::abs(load[0] - load[1]) <= total || children[static_cast<size_t>(frontier.front())].empty()) break;
    const int opened = frontier.front();
    top.push_back(opened);
    frontier.erase(frontier.begin());
    frontier.insert(frontier.end(), children[static_cast<size_t>(opened)].begin(), children[static_cast<size_t>(opened)].end());
  }
  std::vector<int> part(static_cast<size_t>(supernodes), 2);
  std::array<std::int64_t, 2> part_work{0, 0};
  for (int p = 0; p < 2; ++p)
    for (const int root : part_roots[static_cast<size_t>(p)]) part_work[static_cast<size_t>(p)] += work[static_cast<size_t>(root)];
  if (std::min(part_work[0], part_work[1]) < minimum_part_work) {
    // Not worth the other thread: one part, in order.
    std::fill(part.begin(), part.end(), 0);
    part_roots = {};
  }
  for (int p = 0; p < 2; ++p)
    for (const int root : part_roots[static_cast<size_t>(p)]) {
      std::vector<int> stack{root};
      while (!stack.empty()) {
        const int s = stack.back();
        stack.pop_back();
        part[static_cast<size_t>(s)] = p;
        stack.insert(stack.end(), children[static_cast<size_t>(s)].begin(), children[static_cast<size_t>(s)].end());
      }
    }
  in_top_.assign(static_cast<size_t>(size_), 0);
  for (int s = 0; s < supernodes; ++s) {
    const int p = part[static_cast<size_t>(s)];
    parts_[static_cast<size_t>(p)].push_back(s);
    const int columns = first_column_[static_cast<size_t>(s) + 1] - first_column_[static_cast<size_t>(s)];
    split_work_[static_cast<size_t>(p)] += std::int64_t{row_start_[static_cast<size_t>(s) + 1] - row_start_[static_cast<size_t>(s)]} * columns;
    if (p != 2) continue;
    for (int column = first_column_[static_cast<size_t>(s)]; column < first_column_[static_cast<size_t>(s) + 1]; ++column) {
      in_top_[static_cast<size_t>(column)] = 1;
      top_columns_.push_back(column);
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
void SupernodalFactor::forward_supernode(const Scalar* values, int s, double* z, double* buffer, double* top_sums) const {
  const int first = first_column_[static_cast<size_t>(s)], columns = first_column_[static_cast<size_t>(s) + 1] - first;
  const int rows = row_start_[static_cast<size_t>(s) + 1] - row_start_[static_cast<size_t>(s)];
  const int* indices = row_indices_.data() + row_start_[static_cast<size_t>(s)];
  // The rows below start from zero and are added to z after (or, for a part's rows in the
  // top, to the part's own sums of them).
  std::copy(z + first, z + first + columns, buffer);
  std::fill(buffer + columns, buffer + rows, 0.0);
  const Scalar* block = values + value_start_[static_cast<size_t>(s)];
  const double* inverse = inverse_diagonal_.data() + first;
  if (block_product_vectorised())
    avx2_forward_block(block, inverse, rows, columns, buffer);
  else
    portable_forward_block(block, inverse, rows, columns, buffer);
  std::copy(buffer, buffer + columns, z + first);
  for (int i = columns; i < rows; ++i) {
    const int row = indices[i];
    (top_sums && in_top_[static_cast<size_t>(row)] ? top_sums : z)[row] += buffer[i];
  }
}

template <typename Scalar>
void SupernodalFactor::backward_supernode(const Scalar* values, int s, double* z, double* buffer) const {
  const int first = first_column_[static_cast<size_t>(s)], columns = first_column_[static_cast<size_t>(s) + 1] - first;
  const int rows = row_start_[static_cast<size_t>(s) + 1] - row_start_[static_cast<size_t>(s)];
  const int* indices = row_indices_.data() + row_start_[static_cast<size_t>(s)];
  for (int i = 0; i < rows; ++i) buffer[i] = z[indices[i]];  // its own columns first
  const Scalar* block = values + value_start_[static_cast<size_t>(s)];
  const double* inverse = inverse_diagonal_.data() + first;
  if (block_product_vectorised())
    avx2_backward_block(block, inverse, rows, columns, buffer);
  else
    portable_backward_block(block, inverse, rows, columns, buffer);
  std::copy(buffer, buffer + columns, z + first);
}

// Forward: the two parts beside each other, each adding what it takes from the top's rows to
// sums of its own, then those sums to z (part 0's, then part 1's) and the top in order.
// Backward: the top from its last supernode, then the two parts beside each other, each
// reading the top's finished rows. The order of every sum is the split's, not the threads'.
template <typename Scalar>
void SupernodalFactor::sweep(const Scalar* values, double* z, Workspace& work, Executor& executor) const {
  for (const int column : top_columns_) work.top_sums[0][static_cast<size_t>(column)] = work.top_sums[1][static_cast<size_t>(column)] = 0.0;
  auto forward_part = [&](int part) {
    for (const int s : parts_[static_cast<size_t>(part)])
      forward_supernode(values, s, z, work.buffers[static_cast<size_t>(part)].data(), work.top_sums[static_cast<size_t>(part)].data());
  };
  const bool split = !parts_[1].empty();
  if (split)
    executor.run_beside([&] { forward_part(0); }, [&] { forward_part(1); });
  else
    forward_part(0);
  for (const int column : top_columns_) {
    z[column] += work.top_sums[0][static_cast<size_t>(column)];
    z[column] += work.top_sums[1][static_cast<size_t>(column)];
  }
  for (const int s : parts_[2]) forward_supernode(values, s, z, work.buffers[0].data(), nullptr);
  for (auto s = parts_[2].rbegin(); s != parts_[2].rend(); ++s) backward_supernode(values, *s, z, work.buffers[0].data());
  auto backward_part = [&](int part) {
    const std::vector<int>& list = parts_[static_cast<size_t>(part)];
    for (auto s = list.rbegin(); s != list.rend(); ++s) backward_supernode(values, *s, z, work.buffers[static_cast<size_t>(part)].data());
  };
  if (split)
    executor.run_beside([&] { backward_part(0); }, [&] { backward_part(1); });
  else
    backward_part(0);
}

void SupernodalFactor::solve(double* x, Workspace& work, Executor& executor) const {
  work.z.resize(static_cast<size_t>(size_));
  for (auto& buffer : work.buffers) buffer.resize(static_cast<size_t>(tallest_));
  for (auto& sums : work.top_sums) sums.resize(static_cast<size_t>(size_));
  double* z = work.z.data();
  for (int k = 0; k < size_; ++k) z[k] = x[permutation_[static_cast<size_t>(k)]];
  if (!single_values_.empty())
    sweep(single_values_.data(), z, work, executor);
  else
    sweep(double_values_.data(), z, work, executor);
  for (int k = 0; k < size_; ++k) x[permutation_[static_cast<size_t>(k)]] = z[k];
}

}  // namespace incise::physics
