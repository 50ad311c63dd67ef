// CG's start from the last solutions (physics/core/warm_start.hpp): the history a body keeps and
// the Galerkin start CG takes from it.
#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include "physics/core/cg.hpp"
#include "physics/core/warm_start.hpp"

namespace incise::physics {
namespace {

// A random SPD matrix of size n, fixed by the seed.
Eigen::MatrixXd spd(int n, unsigned seed) {
  std::mt19937 random(seed);
  std::uniform_real_distribution<double> uniform(-1, 1);
  Eigen::MatrixXd m(n, n);
  for (int i = 0; i < n; ++i)
    for (int j = 0; j < n; ++j) m(i, j) = uniform(random);
  return m * m.transpose() + n * Eigen::MatrixXd::Identity(n, n);
}

Vector random_vector(int n, unsigned seed) {
  std::mt19937 random(seed);
  std::uniform_real_distribution<double> uniform(-1, 1);
  Vector v(n);
  for (int i = 0; i < n; ++i) v[i] = uniform(random);
  return v;
}

double a_norm(const Eigen::MatrixXd& a, const Vector& v) { return std::sqrt(v.dot(a * v)); }

LinearOperator dense(const Eigen::MatrixXd& a) {
  return [&a](const Vector& p, Vector& out) { out = a * p; };
}

TEST(WarmStart, KeepsTheLastSolutionsOfOneSizeNewestFirst) {
  WarmStart history(3);
  EXPECT_EQ(history.newest(6), Vector::Zero(6));
  EXPECT_TRUE(history.older(6).empty());
  for (int k = 1; k <= 4; ++k) history.record(Vector::Constant(6, k));
  EXPECT_EQ(history.newest(6), Vector::Constant(6, 4));
  ASSERT_EQ(history.older(6).size(), 2u);
  EXPECT_EQ(history.older(6)[0], Vector::Constant(6, 3));
  EXPECT_EQ(history.older(6)[1], Vector::Constant(6, 2));
  // Asked for another size (a body that changed), there is nothing to start from.
  EXPECT_EQ(history.newest(9), Vector::Zero(9));
  EXPECT_TRUE(history.older(9).empty());
  history.zero_node(1);
  for (const Vector& solution : history.solutions()) {
    EXPECT_EQ(solution.segment<3>(3), Vec3::Zero());
    EXPECT_NE(solution[0], 0.0);
  }
  // A solution of another size starts the history over.
  history.record(Vector::Ones(9));
  EXPECT_EQ(history.solutions().size(), 1u);
}

// The Galerkin start of a b whose solution lies in the span of x and the older solutions is
// that solution, and its product is A times it.
TEST(WarmStart, ASolutionInTheSpanOfTheLastOnesIsFoundExactly) {
  const int n = 30;
  const Eigen::MatrixXd a = spd(n, 1);
  std::vector<Vector> older{random_vector(n, 11), random_vector(n, 12), random_vector(n, 13)};
  const Vector newest = random_vector(n, 10);
  const Vector wanted = 0.7 * newest - 1.3 * older[1] + 0.2 * older[2];
  Vector x = newest, product(n);
  galerkin_start(dense(a), a * wanted, {}, older, x, product);
  EXPECT_LT((x - wanted).norm(), 1e-10 * wanted.norm());
  EXPECT_LT((product - a * x).norm(), 1e-10 * product.norm());
}

// For any b it is the A-norm best start in the span: no worse than the newest solution at its
// best scale (the start without older solutions, which it reproduces bit for bit), and better
// when the older ones add anything.
TEST(WarmStart, TheStartIsNoWorseThanTheNewestScaled) {
  const int n = 40;
  const Eigen::MatrixXd a = spd(n, 2);
  const Eigen::LLT<Eigen::MatrixXd> direct(a);
  const Vector b = random_vector(n, 99);
  const Vector exact = direct.solve(b);
  // Three earlier solutions: the exact one, each with its own error of a third of its size.
  const auto near = [&](unsigned seed) {
    const Vector error = random_vector(n, seed);
    return Vector(exact + exact.norm() / 3 * error / error.norm());
  };
  const Vector newest = near(20);
  std::vector<Vector> older{near(21), near(22)};

  Vector scaled = newest, scaled_product(n);
  galerkin_start(dense(a), b, {}, {}, scaled, scaled_product);
  const double a_scale = newest.dot(b) / newest.dot(a * newest);
  EXPECT_EQ(scaled, (a_scale * newest).eval());

  Vector combined = newest, combined_product(n);
  galerkin_start(dense(a), b, {}, older, combined, combined_product);
  EXPECT_LT(a_norm(a, combined - exact), 0.9 * a_norm(a, scaled - exact));
}

// Fixed entries stay zero in the start and its product; nearly parallel solutions (G nearly
// singular) give a bounded start, not huge cancelling multiples.
TEST(WarmStart, FixedEntriesStayZeroAndNearlyParallelSolutionsStayBounded) {
  const int n = 21;  // 7 nodes
  Eigen::MatrixXd a = spd(n, 3);
  const std::vector<std::uint8_t> fixed{0, 1, 0, 0, 0, 0, 0};
  for (int i = 3; i < 6; ++i) {  // A's fixed rows and columns are the identity's
    a.row(i).setZero();
    a.col(i).setZero();
    a(i, i) = 1;
  }
  const Vector base = random_vector(n, 30);
  std::vector<Vector> older;
  for (int j = 1; j < 4; ++j) older.push_back(base * (1 + 0.1 * j) + 1e-13 * random_vector(n, 40 + j));
  Vector b = a * (2.0 * base);
  zero_fixed_nodes(fixed, b);
  Vector x = base, product(n);
  zero_fixed_nodes(fixed, x);
  galerkin_start(dense(a), b, fixed, older, x, product);
  ASSERT_TRUE(x.allFinite());
  EXPECT_EQ(x.segment<3>(3), Vec3::Zero());
  EXPECT_EQ(product.segment<3>(3), Vec3::Zero());
  Vector wanted = 2.0 * base;
  zero_fixed_nodes(fixed, wanted);
  EXPECT_LT((x - wanted).norm(), 1e-6 * wanted.norm());
}

// CG from the combined start converges to the same solution as from a zero start, in fewer
// iterations when the solution is near the span of the earlier ones.
TEST(WarmStart, ConjugateGradientFromTheCombinedStartNeedsFewerIterations) {
  const int n = 200;
  const Eigen::MatrixXd a = spd(n, 4);
  const Eigen::LLT<Eigen::MatrixXd> direct(a);
  std::vector<Vector> solutions;
  for (unsigned j = 0; j < 4; ++j) solutions.push_back(direct.solve(random_vector(n, 50 + j)));
  const Vector exact = 0.3 * solutions[0] + 0.5 * solutions[1] - 0.2 * solutions[2] + 0.4 * solutions[3] +
                       1e-3 * direct.solve(random_vector(n, 60));
  const Vector b = a * exact;
  CgSettings settings;
  settings.tolerance = 1e-10;
  const Vector diagonal = a.diagonal();
  Vector alone = solutions[0];
  const CgResult from_newest = conjugate_gradient(dense(a), b, diagonal, {}, alone, settings);
  settings.start_space = std::span<const Vector>(solutions).subspan(1);
  Vector combined = solutions[0];
  const CgResult from_combination = conjugate_gradient(dense(a), b, diagonal, {}, combined, settings);
  ASSERT_TRUE(from_newest.converged && from_combination.converged);
  EXPECT_LT(from_combination.iterations, from_newest.iterations);
  EXPECT_LT((combined - exact).norm(), 1e-8 * exact.norm());
  EXPECT_LT((alone - exact).norm(), 1e-8 * exact.norm());
}

}  // namespace
}  // namespace incise::physics
