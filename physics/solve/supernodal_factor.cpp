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
  for (int s = 0; s < supernodes(); ++s) {
    const Supernode node = supernode(s);
    tallest_ = std::max(tallest_, node.rows);
    for (int j = 0; j < node.columns; ++j) {
      const double diagonal = layout.values[static_cast<size_t>(node.values + std::int64_t{j} * node.rows + j)];
      check(diagonal > 0 && std::isfinite(diagonal), "column " + std::to_string(node.first + j) + "'s diagonal is not positive");
      inverse_diagonal_[static_cast<size_t>(node.first + j)] = 1.0 / diagonal;
    }
  }
  split(minimum_part_work);
}

namespace {

// The supernodes' elimination tree: a supernode's parent holds its first row below (rows below
// are ancestors only, numbered after it, so children come first); each subtree's work (block
// entries) summed upwards.
struct SupernodeTree {
  std::vector<std::vector<int>> children;
  std::vector<std::int64_t> work;
  std::vector<int> roots;
};

// From the roots down: the heaviest subtree of the frontier goes to the top and its children to
// the frontier, until the frontier's subtrees, dealt heaviest first to the lighter part, balance
// within 1/16 of their work (or nothing is left to open). The two parts' subtree roots.
std::array<std::vector<int>, 2> deal_subtrees(const SupernodeTree& tree) {
  auto work = [&](int s) { return tree.work[static_cast<size_t>(s)]; };
  std::vector<int> frontier = tree.roots;
  std::array<std::vector<int>, 2> part_roots;
  for (;;) {
    std::sort(frontier.begin(), frontier.end(), [&](int a, int b) { return work(a) != work(b) ? work(a) > work(b) : a < b; });
    std::array<std::int64_t, 2> load{0, 0};
    part_roots = {};
    for (const int s : frontier) {
      const size_t lighter = load[1] < load[0] ? 1 : 0;
      load[lighter] += work(s);
      part_roots[lighter].push_back(s);
    }
    if (frontier.empty() || 16 * std::abs(load[0] - load[1]) <= load[0] + load[1]) return part_roots;
    const std::vector<int>& opened = tree.children[static_cast<size_t>(frontier.front())];
    if (opened.empty()) return part_roots;
    frontier.erase(frontier.begin());
    frontier.insert(frontier.end(), opened.begin(), opened.end());
  }
}

}  // namespace

std::array<double, 2> SupernodalFactor::pivot_range() const {
  std::array<double, 2> range{0, 0};
  for (size_t k = 0; k < inverse_diagonal_.size(); ++k) {
    const double pivot = 1.0 / (inverse_diagonal_[k] * inverse_diagonal_[k]);
    range = k == 0 ? std::array<double, 2>{pivot, pivot} : std::array<double, 2>{std::min(range[0], pivot), std::max(range[1], pivot)};
  }
  return range;
}

SupernodalFactor::Supernode SupernodalFactor::supernode(int s) const {
  const auto k = static_cast<size_t>(s);
  return {first_column_[k], first_column_[k + 1] - first_column_[k], row_start_[k + 1] - row_start_[k],
          row_indices_.data() + row_start_[k], value_start_[k]};
}

void SupernodalFactor::split(std::int64_t minimum_part_work) {
  const int supernodes = static_cast<int>(first_column_.size()) - 1;
  std::vector<int> supernode_of(static_cast<size_t>(size_));
  SupernodeTree tree;
  tree.children.resize(static_cast<size_t>(supernodes));
  tree.work.resize(static_cast<size_t>(supernodes));
  for (int s = 0; s < supernodes; ++s) {
    const Supernode node = supernode(s);
    std::fill(supernode_of.begin() + node.first, supernode_of.begin() + node.first + node.columns, s);
  }
  for (int s = 0; s < supernodes; ++s) {
    const Supernode node = supernode(s);
    tree.work[static_cast<size_t>(s)] += std::int64_t{node.rows} * node.columns;
    if (node.rows == node.columns) {
      tree.roots.push_back(s);
      continue;
    }
    const int parent = supernode_of[static_cast<size_t>(node.indices[node.columns])];
    tree.children[static_cast<size_t>(parent)].push_back(s);
    tree.work[static_cast<size_t>(parent)] += tree.work[static_cast<size_t>(s)];
  }
  std::array<std::vector<int>, 2> part_roots = deal_subtrees(tree);
  std::vector<int> part(static_cast<size_t>(supernodes), 2);  // the top unless dealt
  std::array<std::int64_t, 2> part_work{0, 0};
  for (size_t p = 0; p < 2; ++p)
    for (const int root : part_roots[p]) part_work[p] += tree.work[static_cast<size_t>(root)];
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
        stack.insert(stack.end(), tree.children[static_cast<size_t>(s)].begin(), tree.children[static_cast<size_t>(s)].end());
      }
    }
  in_top_.assign(static_cast<size_t>(size_), 0);
  for (int s = 0; s < supernodes; ++s) {
    const auto p = static_cast<size_t>(part[static_cast<size_t>(s)]);
    const Supernode node = supernode(s);
    parts_[p].push_back(s);
    split_work_[p] += std::int64_t{node.rows} * node.columns;
    if (p != 2) continue;
    for (int column = node.first; column < node.first + node.columns; ++column) {
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

enum class Sweep { forward, backward };

// A block's sweep, compiled for AVX2 and for the baseline (the same bits, above), chosen at
// run time as the block products are (block_product_vectorised: tests force the portable one).
template <Sweep sweep, typename Scalar>
[[gnu::always_inline]] inline void sweep_block(const Scalar* block, const double* inverse_diagonal, int rows, int columns,
                                               double* buffer) {
  if constexpr (sweep == Sweep::forward)
    forward_block(block, inverse_diagonal, rows, columns, buffer);
  else
    backward_block(block, inverse_diagonal, rows, columns, buffer);
}
template <Sweep sweep, typename Scalar>
__attribute__((target("avx2"))) void avx2_sweep_block(const Scalar* block, const double* inverse_diagonal, int rows,
                                                      int columns, double* buffer) {
  sweep_block<sweep>(block, inverse_diagonal, rows, columns, buffer);
}
template <Sweep sweep, typename Scalar>
void portable_sweep_block(const Scalar* block, const double* inverse_diagonal, int rows, int columns, double* buffer) {
  sweep_block<sweep>(block, inverse_diagonal, rows, columns, buffer);
}
template <Sweep sweep, typename Scalar>
void run_sweep_block(const Scalar* block, const double* inverse_diagonal, int rows, int columns, double* buffer) {
  if (block_product_vectorised())
    avx2_sweep_block<sweep>(block, inverse_diagonal, rows, columns, buffer);
  else
    portable_sweep_block<sweep>(block, inverse_diagonal, rows, columns, buffer);
}

}  // namespace

template <typename Scalar>
void SupernodalFactor::forward_supernode(const Scalar* values, int s, double* z, double* buffer, double* top_sums) const {
  const Supernode node = supernode(s);
  // The rows below start from zero and are added to z after (or, for a part's rows in the
  // top, to the part's own sums of them).
  std::copy(z + node.first, z + node.first + node.columns, buffer);
  std::fill(buffer + node.columns, buffer + node.rows, 0.0);
  run_sweep_block<Sweep::forward>(values + node.values, inverse_diagonal_.data() + node.first, node.rows, node.columns,
                                  buffer);
  std::copy(buffer, buffer + node.columns, z + node.first);
  for (int i = node.columns; i < node.rows; ++i) {
    const int row = node.indices[i];
    (top_sums && in_top_[static_cast<size_t>(row)] ? top_sums : z)[row] += buffer[i];
  }
}

template <typename Scalar>
void SupernodalFactor::backward_supernode(const Scalar* values, int s, double* z, double* buffer) const {
  const Supernode node = supernode(s);
  for (int i = 0; i < node.rows; ++i) buffer[i] = z[node.indices[i]];  // its own columns first
  run_sweep_block<Sweep::backward>(values + node.values, inverse_diagonal_.data() + node.first, node.rows, node.columns,
                                   buffer);
  std::copy(buffer, buffer + node.columns, z + node.first);
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
