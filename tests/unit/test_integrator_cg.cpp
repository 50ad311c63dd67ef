#include <gtest/gtest.h>

#include <Eigen/Cholesky>
#include <Eigen/LU>
#include <Eigen/Core>
#include <cmath>
#include <cstdint>
#include <limits>
#include <vector>

#include "physics/core/cg.hpp"
#include "physics/core/stopwatch.hpp"
#include "physics/solve/bicgstab.hpp"

namespace incise::physics {
namespace {

using Dense = Eigen::MatrixXd;

// Deterministic pseudo-random values in [-1, 1] (a fixed linear congruential sequence, so the
// test matrices do not depend on the standard library's distributions).
class Sequence {
 public:
  explicit Sequence(uint64_t seed) : state_(seed) {}
  double next() {
    state_ = state_ * 6364136223846793005ULL + 1442695040888963407ULL;
    return static_cast<double>(state_ >> 11) / static_cast<double>(1ULL << 53) * 2.0 - 1.0;
  }

 private:
  uint64_t state_;
};

// SPD with a spread diagonal, so Jacobi preconditioning has work to do.
Dense make_spd(int size, uint64_t seed) {
  Sequence sequence(seed);
  Dense b(size, size);
  for (int i = 0; i < size; ++i)
    for (int j = 0; j < size; ++j) b(i, j) = sequence.next();
  Dense a = b.transpose() * b + size * Dense::Identity(size, size);
  for (int i = 0; i < size; ++i) {
    const double scale = std::pow(10.0, 2.0 * i / size);
    a.row(i) *= scale;
    a.col(i) *= scale;
  }
  return a;
}

Vector make_vector(int size, uint64_t seed) {
  Sequence sequence(seed);
  Vector v(size);
  for (int i = 0; i < size; ++i) v[i] = sequence.next();
  return v;
}

LinearOperator dense_operator(const Dense& a) {
  return [&a](const Vector& p, Vector& out) { out.noalias() = a * p; };
}

TEST(ConjugateGradient, SolvesSpdSystemToTolerance) {
  const int size = 36;
  const Dense a = make_spd(size, 1);
  const Vector b = make_vector(size, 2);
  Vector x = Vector::Zero(size);
  CgSettings settings;
  settings.tolerance = 1e-10;
  const CgResult result = conjugate_gradient(dense_operator(a), b, a.diagonal(), {}, x, settings);
  EXPECT_TRUE(result.converged);
  EXPECT_FALSE(result.nonfinite);
  EXPECT_GT(result.iterations, 0);
  EXPECT_LE(result.relative_residual, 1e-10);
  EXPECT_LE((b - a * x).norm() / b.norm(), 1e-10);
  const Vector reference = a.llt().solve(b);
  EXPECT_LE((x - reference).norm() / reference.norm(), 1e-8);
}

// CG iterating on an approximation of the system (its entries rounded to float, or off by
// 10 %) with the exact operator given: converged means converged on the exact system, the
// reported residual is the exact one, and an approximation is refined by restarts (the float
// rounding, on this matrix whose diagonal spans 1e4 and at 1e-9, needs one); without `exact` the
// 10 % operator solves its own system, far from this one.
TEST(ConjugateGradient, AnApproximateOperatorConvergesOnTheExactOne) {
  const int size = 48;
  const Dense a = make_spd(size, 11);
  const Vector b = make_vector(size, 12);
  CgSettings settings;
  settings.tolerance = 1e-9;
  const Vector inverse_diagonal = a.diagonal().cwiseInverse();
  const Preconditioner jacobi = [&](const Vector& r, Vector& z) { z = inverse_diagonal.cwiseProduct(r); };
  const LinearOperator exact = dense_operator(a);
  const Dense rounded = a.cast<float>().cast<double>();
  Dense perturbed = a;
  for (int i = 0; i < size; ++i)
    for (int j = 0; j <= i; ++j) perturbed(i, j) = perturbed(j, i) = a(i, j) * (1.0 + 0.1 * std::sin(i + 3.0 * j));
  for (const Dense* approximation : std::vector<const Dense*>{&rounded, &perturbed}) {
    Vector x = Vector::Zero(size);
    const CgResult result =
        preconditioned_conjugate_gradient(dense_operator(*approximation), b, jacobi, {}, x, settings, &exact);
    EXPECT_TRUE(result.converged);
    EXPECT_LE(result.relative_residual, 1e-9);
    EXPECT_NEAR(result.relative_residual, (b - a * x).norm() / b.norm(), 1e-15);
    if (approximation == &rounded) {
      EXPECT_GE(result.exact_checks, 1);
      EXPECT_LE(result.exact_checks, 2);
    } else {
      EXPECT_GE(result.exact_checks, 3);  // restarted, each round gaining about a decade
      Vector own = Vector::Zero(size);
      preconditioned_conjugate_gradient(dense_operator(perturbed), b, jacobi, {}, own, settings);
      EXPECT_GT((b - a * own).norm() / b.norm(), 1e-3);
    }
  }
}

TEST(ConjugateGradient, StopsAtMaxIterationsUnconverged) {
  const int size = 36;
  const Dense a = make_spd(size, 3);
  const Vector b = make_vector(size, 4);
  Vector x = Vector::Zero(size);
  CgSettings settings;
  settings.tolerance = 1e-14;
  settings.max_iterations = 3;
  const CgResult result = conjugate_gradient(dense_operator(a), b, a.diagonal(), {}, x, settings);
  EXPECT_FALSE(result.converged);
  EXPECT_EQ(result.iterations, 3);
  EXPECT_GT(result.relative_residual, 1e-14);
  EXPECT_NEAR(result.relative_residual, (b - a * x).norm() / b.norm(), 1e-12);
}

// Real time (issue 29): a deadline already passed stops CG after its minimum of iterations; a
// recorded stop repeats exactly the iterate of the CG it stopped (the same x as a CG capped
// at that many iterations), and a deadline far ahead changes nothing.
TEST(ConjugateGradient, ABudgetStopsAtTheDeadlineAndARecordedStopRepeatsTheIterate) {
  const int size = 36;
  const Dense a = make_spd(size, 3);
  const Vector b = make_vector(size, 4);
  CgSettings settings;
  settings.tolerance = 1e-12;

  Vector converged = Vector::Zero(size);
  const CgResult full = conjugate_gradient(dense_operator(a), b, a.diagonal(), {}, converged, settings);
  ASSERT_TRUE(full.converged);
  ASSERT_GT(full.iterations, 6);

  CgSettings late = settings;
  late.budget.deadline_ns = 1;  // long past
  late.budget.min_iterations = 4;
  Vector stopped = Vector::Zero(size);
  const CgResult at_deadline = conjugate_gradient(dense_operator(a), b, a.diagonal(), {}, stopped, late);
  EXPECT_TRUE(at_deadline.stopped_by_budget);
  EXPECT_FALSE(at_deadline.converged);
  EXPECT_EQ(at_deadline.iterations, 4);

  CgSettings recorded = settings;
  recorded.budget.stop_at = 4;
  recorded.budget.deadline_ns = steady_now_ns() + 3'600'000'000'000;  // ignored beside a recorded stop
  Vector repeated = Vector::Zero(size);
  const CgResult repeat = conjugate_gradient(dense_operator(a), b, a.diagonal(), {}, repeated, recorded);
  EXPECT_TRUE(repeat.stopped_by_budget);
  EXPECT_EQ(repeat.iterations, 4);
  EXPECT_EQ(repeated, stopped);
  EXPECT_GT((repeated - converged).norm(), 1e-6 * converged.norm());

  CgSettings ahead = settings;
  ahead.budget.deadline_ns = steady_now_ns() + 3'600'000'000'000;
  Vector unhurried = Vector::Zero(size);
  const CgResult in_time = conjugate_gradient(dense_operator(a), b, a.diagonal(), {}, unhurried, ahead);
  EXPECT_TRUE(in_time.converged);
  EXPECT_FALSE(in_time.stopped_by_budget);
  EXPECT_EQ(unhurried, converged);
}

TEST(ConjugateGradient, RespectsFixedMask) {
  const int nodes = 12;
  const int size = 3 * nodes;
  const Dense a = make_spd(size, 5);
  const Vector b = make_vector(size, 6);
  std::vector<uint8_t> fixed(nodes, 0);
  fixed[0] = fixed[5] = fixed[11] = 1;
  Vector x = Vector::Constant(size, 7.0);  // fixed entries must be overwritten with zero
  CgSettings settings;
  settings.tolerance = 1e-12;
  const CgResult result =
      conjugate_gradient(dense_operator(a), b, a.diagonal(), fixed, x, settings);
  ASSERT_TRUE(result.converged);

  std::vector<int> free_components;
  for (int component = 0; component < size; ++component) {
    if (fixed[component / 3]) {
      EXPECT_EQ(x[component], 0.0) << "component " << component;
    } else {
      free_components.push_back(component);
    }
  }
  const int free_count = static_cast<int>(free_components.size());
  Dense reduced(free_count, free_count);
  Vector reduced_b(free_count);
  for (int i = 0; i < free_count; ++i) {
    reduced_b[i] = b[free_components[i]];
    for (int j = 0; j < free_count; ++j) reduced(i, j) = a(free_components[i], free_components[j]);
  }
  const Vector reference = reduced.llt().solve(reduced_b);
  for (int i = 0; i < free_count; ++i) {
    EXPECT_NEAR(x[free_components[i]], reference[i], 1e-9 * reference.cwiseAbs().maxCoeff());
  }
}

TEST(ConjugateGradient, ZeroRightHandSideGivesZero) {
  const Dense a = make_spd(9, 7);
  Vector x = Vector::Constant(9, 3.0);
  const CgResult result =
      conjugate_gradient(dense_operator(a), Vector::Zero(9), a.diagonal(), {}, x);
  EXPECT_TRUE(result.converged);
  EXPECT_EQ(result.iterations, 0);
  EXPECT_EQ(x, Vector::Zero(9));
}

TEST(ConjugateGradient, ReportsNonFiniteOperatorAndKeepsFiniteIterate) {
  const int size = 12;
  const Dense a = make_spd(size, 8);
  const Vector b = make_vector(size, 9);
  int calls = 0;
  const LinearOperator poisoned = [&](const Vector& p, Vector& out) {
    out.noalias() = a * p;
    if (++calls >= 3) out[4] = std::numeric_limits<double>::quiet_NaN();
  };
  Vector x = Vector::Zero(size);
  CgSettings settings;
  settings.tolerance = 1e-14;
  const CgResult result = conjugate_gradient(poisoned, b, a.diagonal(), {}, x, settings);
  EXPECT_TRUE(result.nonfinite);
  EXPECT_FALSE(result.converged);
  EXPECT_TRUE(x.allFinite());
  EXPECT_EQ(result.iterations, 1);  // call 1: initial residual, call 2: iteration 1
  EXPECT_NE(x, Vector::Zero(size));
}

TEST(ConjugateGradient, ReportsNonFiniteRightHandSide) {
  const Dense a = make_spd(6, 10);
  Vector b = make_vector(6, 11);
  b[2] = std::numeric_limits<double>::infinity();
  Vector x = Vector::Zero(6);
  const CgResult result = conjugate_gradient(dense_operator(a), b, a.diagonal(), {}, x);
  EXPECT_TRUE(result.nonfinite);
  EXPECT_TRUE(x.allFinite());
}

TEST(ConjugateGradient, ReportsNonPositiveCurvature) {
  const Dense a = -Dense::Identity(6, 6);
  Vector x = Vector::Zero(6);
  const CgResult result =
      conjugate_gradient(dense_operator(a), make_vector(6, 12), Vector::Ones(6), {}, x);
  EXPECT_TRUE(result.non_positive_curvature);
  EXPECT_FALSE(result.converged);
  EXPECT_TRUE(x.allFinite());
}

TEST(ConjugateGradient, IsBitwiseDeterministic) {
  const Dense a = make_spd(30, 13);
  const Vector b = make_vector(30, 14);
  Vector first = Vector::Zero(30), second = Vector::Zero(30);
  conjugate_gradient(dense_operator(a), b, a.diagonal(), {}, first);
  conjugate_gradient(dense_operator(a), b, a.diagonal(), {}, second);
  EXPECT_EQ(first, second);
}

TEST(ConjugateGradient, RejectsMismatchedSizes) {
  const Dense a = make_spd(6, 15);
  Vector x = Vector::Zero(5);
  EXPECT_THROW(conjugate_gradient(dense_operator(a), make_vector(6, 1), a.diagonal(), {}, x),
               std::invalid_argument);
  Vector y = Vector::Zero(6);
  EXPECT_THROW(conjugate_gradient(dense_operator(a), make_vector(6, 1), a.diagonal(),
                                  std::vector<uint8_t>(3, 0), y),
               std::invalid_argument);
}

}  // namespace
// BiCGSTAB (physics/solve/bicgstab.hpp) on a non-symmetric system, SPD plus a skew part as
// large as its symmetric one, two nodes fixed: the free part against a dense LU of the free
// rows and columns, zero on the fixed ones, and a guess that is the solution ends at once.
TEST(Bicgstab, SolvesANonSymmetricSystemWithFixedNodes) {
  const int size = 36;
  const Dense spd = make_spd(size, 5);
  Dense skew = Dense::Zero(size, size);
  Sequence sequence(6);
  for (int i = 0; i < size; ++i)
    for (int j = 0; j < i; ++j) {
      skew(i, j) = 0.5 * sequence.next() * std::sqrt(spd(i, i) * spd(j, j));
      skew(j, i) = -skew(i, j);
    }
  const Dense a = spd + skew;
  ASSERT_GT((a - a.transpose()).norm(), 0.1 * a.norm());
  const Vector b = make_vector(size, 7);
  const std::vector<uint8_t> fixed = {0, 1, 0, 0, 0, 0, 0, 0, 0, 0, 1, 0};
  const Vector inverse = jacobi_inverse(a.diagonal());
  const Preconditioner jacobi = [&](const Vector& r, Vector& out) { out = inverse.cwiseProduct(r); };
  CgSettings settings;
  settings.tolerance = 1e-10;
  settings.max_iterations = 500;
  Vector x = Vector::Ones(size);
  const CgResult result = bicgstab(dense_operator(a), b, jacobi, fixed, x, settings);
  ASSERT_TRUE(result.converged);
  EXPECT_LE(result.relative_residual, 1e-10);
  std::vector<int> free;
  for (int d = 0; d < size; ++d)
    if (!fixed[d / 3]) free.push_back(d);
    else EXPECT_EQ(x[d], 0.0) << "fixed dof " << d;
  Dense reduced(free.size(), free.size());
  Vector rhs(free.size());
  for (size_t r = 0; r < free.size(); ++r) {
    rhs[r] = b[free[r]];
    for (size_t c = 0; c < free.size(); ++c) reduced(r, c) = a(free[r], free[c]);
  }
  const Vector reference = reduced.partialPivLu().solve(rhs);
  for (size_t r = 0; r < free.size(); ++r) EXPECT_NEAR(x[free[r]], reference[r], 1e-8 * reference.norm());
  Vector again = x;
  const CgResult restart = bicgstab(dense_operator(a), b, jacobi, fixed, again, settings);
  EXPECT_TRUE(restart.converged);
  EXPECT_EQ(restart.iterations, 0);
}

}  // namespace incise::physics
