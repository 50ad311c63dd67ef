// The coarse corrections' own Cholesky solve (physics/solve/supernodal_factor.hpp) against
// Eigen's, on an elasticity-like SPD matrix wide enough for CHOLMOD to make multi-column
// supernodes: the double factor solves to round-off, the float one is a symmetric positive
// operator close to A^-1, both kernels give the same bits, and bad layouts are refused.
#include "physics/solve/block_product.hpp"
#include "physics/solve/rest_factor.hpp"
#include "physics/solve/supernodal_factor.hpp"

#include <gtest/gtest.h>

#include <Eigen/SparseCholesky>

#include <cstring>
#include <random>
#include <thread>
#include <stdexcept>
#include <vector>

namespace incise::physics {
namespace {

using SparseMatrix = Eigen::SparseMatrix<double>;

// The lower triangle of a 3-dof-per-node matrix on an n^3 grid: every node coupled to its 26
// neighbours by random symmetric 3x3 blocks, the diagonal blocks made dominant (SPD).
SparseMatrix grid_matrix(int n, unsigned seed) {
  std::mt19937 random(seed);
  std::uniform_real_distribution<double> entry(-1.0, 1.0);
  const int nodes = n * n * n;
  auto index = [n](int x, int y, int z) { return (z * n + y) * n + x; };
  std::vector<Eigen::Triplet<double>> triplets;
  std::vector<double> row_sums(3 * static_cast<size_t>(nodes), 0.0);
  for (int z = 0; z < n; ++z)
    for (int y = 0; y < n; ++y)
      for (int x = 0; x < n; ++x)
        for (int dz = -1; dz <= 1; ++dz)
          for (int dy = -1; dy <= 1; ++dy)
            for (int dx = -1; dx <= 1; ++dx) {
              const int X = x + dx, Y = y + dy, Z = z + dz;
              if (X < 0 || Y < 0 || Z < 0 || X >= n || Y >= n || Z >= n) continue;
              const int a = index(x, y, z), b = index(X, Y, Z);
              if (b >= a) continue;  // each pair once, below the diagonal
              for (int i = 0; i < 3; ++i)
                for (int j = 0; j < 3; ++j) {
                  const double value = entry(random);
                  triplets.emplace_back(3 * a + i, 3 * b + j, value);
                  row_sums[static_cast<size_t>(3 * a + i)] += std::abs(value);
                  row_sums[static_cast<size_t>(3 * b + j)] += std::abs(value);
                }
            }
  for (int node = 0; node < nodes; ++node)
    for (int i = 0; i < 3; ++i) {
      for (int j = 0; j < i; ++j) {
        const double value = 0.1 * entry(random);
        triplets.emplace_back(3 * node + i, 3 * node + j, value);
        row_sums[static_cast<size_t>(3 * node + i)] += std::abs(value);
        row_sums[static_cast<size_t>(3 * node + j)] += std::abs(value);
      }
    }
  for (int k = 0; k < 3 * nodes; ++k) triplets.emplace_back(k, k, 1.05 * row_sums[static_cast<size_t>(k)] + 0.01);
  SparseMatrix lower(3 * nodes, 3 * nodes);
  lower.setFromTriplets(triplets.begin(), triplets.end());
  return lower;
}

Eigen::VectorXd random_vector(Eigen::Index size, unsigned seed) {
  std::mt19937 random(seed);
  std::uniform_real_distribution<double> entry(-1.0, 1.0);
  Eigen::VectorXd v(size);
  for (Eigen::Index i = 0; i < size; ++i) v[i] = entry(random);
  return v;
}

Eigen::VectorXd solved(const SupernodalFactor& factor, Eigen::VectorXd b) {
  SupernodalFactor::Workspace work;
  factor.solve(b.data(), work);
  return b;
}

SparseMatrix full(const SparseMatrix& lower) { return lower.selfadjointView<Eigen::Lower>(); }

// Both builders' factors; under ThreadSanitizer, which cannot see OpenBLAS's and OpenMP's
// synchronisation (rest_factor.hpp), the simplicial one alone.
// `minimum_part_work`: as the solver's, or 0 to split whatever the sizes.
std::vector<SupernodalFactor> factors(const SparseMatrix& lower, bool single_precision,
                                      std::int64_t minimum_part_work = SupernodalFactor::default_minimum_part_work) {
  std::vector<SupernodalFactor> out;
  if (default_factor_backend() == FactorBackend::cholmod) {
    use_single_threaded_blas();
    out.push_back(SupernodalFactor::with_cholmod(lower, single_precision, minimum_part_work));
  }
  out.push_back(SupernodalFactor::with_simplicial(lower, single_precision, minimum_part_work));
  return out;
}

SupernodalFactor default_factor(const SparseMatrix& lower, bool single_precision) { return factors(lower, single_precision).front(); }

TEST(SupernodalFactor, InDoubleSolvesAsEigenDoes) {
  const SparseMatrix lower = grid_matrix(7, 1);
  const Eigen::VectorXd b = random_vector(lower.rows(), 2);
  const Eigen::VectorXd reference = Eigen::SimplicialLLT<SparseMatrix>(full(lower)).solve(b);
  // CHOLMOD's supernodes span several columns (the dense kernels' triangles and rows below),
  // the simplicial factor's one each.
  const std::vector<SupernodalFactor> both = factors(lower, false);
  if (both.size() == 2) {
    EXPECT_LT(both.front().supernodes(), lower.rows() / 4);
  }
  EXPECT_EQ(both.back().supernodes(), lower.rows());
  for (const SupernodalFactor& factor : both) {
    ASSERT_EQ(factor.size(), lower.rows());
    EXPECT_GT(factor.factor_nonzeros(), lower.nonZeros());  // fill-in
    const Eigen::VectorXd x = solved(factor, b);
    EXPECT_LE((x - reference).norm(), 1e-12 * reference.norm());
    EXPECT_LE((full(lower) * x - b).norm(), 1e-12 * b.norm());
  }
}

TEST(SupernodalFactor, InFloatIsASymmetricPositiveOperatorCloseToTheInverse) {
  const SparseMatrix lower = grid_matrix(7, 3);
  for (const SupernodalFactor& factor : factors(lower, true)) {
    const Eigen::VectorXd u = random_vector(lower.rows(), 4), v = random_vector(lower.rows(), 5);
    const Eigen::VectorXd mu = solved(factor, u), mv = solved(factor, v);
    // (L' L'^T)^-1 with L' the rounded factor: symmetric up to the double sums' round-off,
    // positive, and within float's rounding (times the conditioning) of A^-1.
    EXPECT_NEAR(v.dot(mu), u.dot(mv), 1e-12 * std::abs(v.dot(mu)) + 1e-15);
    EXPECT_GT(u.dot(mu), 0.0);
    EXPECT_GT(v.dot(mv), 0.0);
    const double residual = (full(lower) * mu - u).norm() / u.norm();
    EXPECT_LE(residual, 1e-5);
    EXPECT_GT(residual, 1e-12);  // it is the float factor's solve, not the double one's
  }
}

TEST(SupernodalFactor, BothKernelsGiveTheSameBits) {
  const SparseMatrix lower = grid_matrix(6, 6);
  const Eigen::VectorXd b = random_vector(lower.rows(), 7);
  for (const bool single : {true, false}) {
    const SupernodalFactor factor = default_factor(lower, single);
    set_block_product_vectorised(true);
    const Eigen::VectorXd vectorised = solved(factor, b);
    set_block_product_vectorised(false);
    const Eigen::VectorXd portable = solved(factor, b);
    set_block_product_vectorised(true);
    ASSERT_EQ(vectorised.size(), portable.size());
    EXPECT_EQ(0, std::memcmp(vectorised.data(), portable.data(), sizeof(double) * static_cast<size_t>(b.size())))
        << (single ? "float" : "double") << " factor";
  }
}

// run_beside with side() on a thread of its own, or on the caller before own(): the two
// halves of the solve beside each other, or in the other order.
class TwoThreads final : public Executor {
 public:
  explicit TwoThreads(bool side_first) : side_first_(side_first) {}
  int thread_count() const override { return 2; }
  void parallel_for(int count, const std::function<void(int, int)>& task, int) override { task(0, count); }
  void run_beside(const std::function<void()>& own, const std::function<void()>& side) override {
    if (side_first_) {
      side();
      own();
      return;
    }
    std::thread other(side);
    own();
    other.join();
  }

 private:
  bool side_first_;
};

TEST(SupernodalFactor, SplitsItsTreeInTwoHalvesWhoseSolveHasTheBitsOfAnyOrder) {
  const SparseMatrix lower = grid_matrix(8, 9);
  const Eigen::VectorXd b = random_vector(lower.rows(), 10);
  for (const SupernodalFactor& factor : factors(lower, true, 0)) {
    const auto work = factor.split_work();
    // Two parts of about equal work (within 1/16 of theirs when the split stops opening the
    // tree; the top here is the grid's dense middle separators).
    EXPECT_GT(work[0], 0);
    EXPECT_GT(work[1], 0);
    EXPECT_LE(8 * std::abs(work[0] - work[1]), work[0] + work[1]);
    const Eigen::VectorXd serial = solved(factor, b);
    for (const bool side_first : {false, true}) {
      TwoThreads executor(side_first);
      SupernodalFactor::Workspace scratch;
      Eigen::VectorXd x = b;
      factor.solve(x.data(), scratch, executor);
      EXPECT_EQ(0, std::memcmp(x.data(), serial.data(), sizeof(double) * static_cast<size_t>(b.size())));
    }
    EXPECT_LE((full(lower) * serial - b).norm(), 1e-5 * b.norm());
  }
  // Below the minimum a part needs, one part: the same solve in order.
  for (const SupernodalFactor& factor : factors(lower, true)) {
    const auto work = factor.split_work();
    EXPECT_EQ(work[1], 0);
    EXPECT_EQ(work[2], 0);
  }
}

TEST(SupernodalFactor, RefusesAMatrixThatIsNotPositiveDefinite) {
  SparseMatrix lower = grid_matrix(3, 8);
  lower.coeffRef(5, 5) = -1.0;
  EXPECT_THROW(factors(lower, true), std::runtime_error);
  EXPECT_THROW(SupernodalFactor::with_simplicial(lower, true), std::runtime_error);
}

// A 2x2 factor as one supernode of two columns: L = [[2, 0], [1, 3]].
struct TwoByTwo {
  std::vector<int> permutation{1, 0}, first_column{0, 2}, row_start{0, 2}, row_indices{0, 1};
  std::vector<std::int64_t> value_start{0, 4};
  std::vector<double> values{2, 1, 0, 3};
  SupernodalLayout layout() const {
    return {2, permutation, first_column, row_start, row_indices, value_start, values};
  }
};

TEST(SupernodalFactor, SolvesAHandMadeLayout) {
  const TwoByTwo two;
  const SupernodalFactor factor(two.layout(), false);
  // P A P^T = L L^T = [[4, 2], [2, 10]] with P swapping the rows: A = [[10, 2], [2, 4]].
  Eigen::Vector2d b(14, 10);  // A (1, 2)
  SupernodalFactor::Workspace work;
  factor.solve(b.data(), work);
  EXPECT_NEAR(b[0], 1.0, 1e-15);
  EXPECT_NEAR(b[1], 2.0, 1e-15);
}

TEST(SupernodalFactor, RefusesALayoutThatIsNotOne) {
  auto refused = [](const TwoByTwo& two) {
    EXPECT_THROW(SupernodalFactor(two.layout(), true), std::invalid_argument);
  };
  TwoByTwo repeated;
  repeated.permutation = {0, 0};
  refused(repeated);
  TwoByTwo not_its_columns;
  not_its_columns.row_indices = {1, 0};
  refused(not_its_columns);
  TwoByTwo short_block;
  short_block.value_start = {0, 3};
  short_block.values.resize(3);
  refused(short_block);
  TwoByTwo negative;
  negative.values[3] = -3;
  refused(negative);
  TwoByTwo uncovered;
  uncovered.first_column = {0, 1};
  refused(uncovered);
}

}  // namespace
}  // namespace incise::physics
