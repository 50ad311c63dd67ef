// llt3_solve (physics/efg/llt3.hpp) against Eigen::LLT<Mat3>: the same success and the same
// bits, over the rotation extraction's Newton matrices and over general symmetric ones.
#include "physics/efg/llt3.hpp"

#include <gtest/gtest.h>

#include <Eigen/Cholesky>

#include <cmath>
#include <cstring>
#include <limits>
#include <random>

namespace incise::physics {
namespace {

bool same_bits(const Vec3& a, const Vec3& b) { return std::memcmp(a.data(), b.data(), sizeof(double) * 3) == 0; }

void expect_as_eigen(const Mat3& a, const Vec3& b) {
  const Eigen::LLT<Mat3> llt(a);
  Vec3 x;
  const bool solved = llt3_solve(a, b, x);
  ASSERT_EQ(solved, llt.info() == Eigen::Success) << a;
  if (solved) {
    const Vec3 reference = llt.solve(b);
    ASSERT_TRUE(same_bits(x, reference)) << a << "\n" << x.transpose() << " vs " << reference.transpose();
  }
}

TEST(Llt3, MatchesEigenBitwise) {
  std::mt19937_64 random(29);
  std::normal_distribution<double> normal;
  for (int sample = 0; sample < 200000; ++sample) {
    Mat3 n;
    for (int i = 0; i < 9; ++i) n(i) = normal(random) * (sample % 3 == 0 ? 1e-3 : 1.0);
    if (sample % 2 == 0) n += Mat3::Identity();  // near a rotation: the extraction's case
    const Vec3 b(normal(random), normal(random), normal(random));
    // The Newton matrix tr(N) I - sym N, positive definite or not.
    expect_as_eigen(n.trace() * Mat3::Identity() - 0.5 * (n + n.transpose()), b);
    expect_as_eigen(0.5 * (n + n.transpose()), b);  // often indefinite
    expect_as_eigen(n * n.transpose(), b);          // positive semi-definite
  }
}

TEST(Llt3, FailsAndPassesWhereEigenDoes) {
  const Vec3 b(1, 2, 3);
  expect_as_eigen(Mat3::Zero(), b);
  expect_as_eigen(Mat3::Identity(), b);
  expect_as_eigen(-Mat3::Identity(), b);
  Mat3 rank_one = Vec3(1, 2, 3) * Vec3(1, 2, 3).transpose();
  expect_as_eigen(rank_one, b);
  Mat3 nan = Mat3::Identity();
  nan(1, 1) = std::numeric_limits<double>::quiet_NaN();
  const Eigen::LLT<Mat3> llt(nan);
  Vec3 x;
  EXPECT_EQ(llt3_solve(nan, b, x), llt.info() == Eigen::Success);
}

}  // namespace
}  // namespace incise::physics
