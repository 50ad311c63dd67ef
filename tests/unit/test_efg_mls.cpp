// The quartic spline (seed-004 §1.4, r^3 coefficient corrected to 8) and the linear MLS shape
// functions of the EFG model: consistency at every integration point, gradients against
// finite differences.
#include "physics/efg/corotational_efg.hpp"
#include "physics/efg/kernel.hpp"
#include "physics/efg/mls.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <numbers>
#include <vector>

namespace incise::physics {
namespace {

const Material tissue{30e3, 0.45, 1050};

TEST(EfgKernel, CorrectedQuarticSplineValues) {
  const double h = 0.37;
  const double peak = 105.0 / (16.0 * std::numbers::pi * h * h * h);
  EXPECT_DOUBLE_EQ(quartic_spline(0.0, h), peak);
  // The expanded polynomial 1 - 6q^2 + 8q^3 - 3q^4 at a few points (the printed thesis form,
  // with r^3 coefficient 1, gives -7 at q = 1 and fails these).
  for (double q : {0.1, 0.25, 0.5, 0.8, 0.99}) {
    const double expanded = 1 - 6 * q * q + 8 * q * q * q - 3 * q * q * q * q;
    EXPECT_NEAR(quartic_spline(q * h, h), peak * expanded, 1e-12 * peak) << "q = " << q;
  }
  EXPECT_EQ(quartic_spline(h, h), 0.0);
  EXPECT_EQ(quartic_spline(1.5 * h, h), 0.0);
  EXPECT_EQ(quartic_spline_derivative(h, h), 0.0);
  EXPECT_EQ(quartic_spline_derivative(0.0, h), 0.0);
  // w''(h) = 0 too: w' falls like (h - r)^2 near h, so w'(h - d) / d vanishes with d.
  for (double step : {1e-3 * h, 1e-5 * h}) {
    EXPECT_NEAR(quartic_spline_derivative(h - step, h) / step, 0.0, 50 * step / h * peak / h / h)
        << "step " << step;
  }
  EXPECT_GT(quartic_spline(0.999 * h, h), 0.0);
}

TEST(EfgKernel, IntegratesToOneOverTheBall) {
  const double h = 0.02;
  // Simpson's rule on 4 pi r^2 w(r), a polynomial of degree 6 on [0, h]: 2000 intervals give
  // far better than 1e-10.
  const int intervals = 2000;
  double sum = 0;
  for (int i = 0; i <= intervals; ++i) {
    const double r = h * i / intervals;
    const double weight = (i == 0 || i == intervals) ? 1 : (i % 2 == 1 ? 4 : 2);
    sum += weight * 4 * std::numbers::pi * r * r * quartic_spline(r, h);
  }
  EXPECT_NEAR(sum * h / intervals / 3, 1.0, 1e-10);
}

TEST(EfgKernel, DerivativeMatchesFiniteDifferences) {
  const double h = 0.05;
  for (double q : {0.05, 0.2, 0.45, 0.7, 0.93}) {
    const double r = q * h, step = 1e-6 * h;
    const double difference =
        (quartic_spline(r + step, h) - quartic_spline(r - step, h)) / (2 * step);
    EXPECT_NEAR(quartic_spline_derivative(r, h), difference,
                1e-7 * std::abs(quartic_spline_derivative(0.5 * h, h)))
        << "q = " << q;
  }
}

// An ellipsoid with a planar cut, so the check also covers partial cubes and the neighbourhoods
// re-selected around the cut.
CorotationalEfg ellipsoid_model(int neighbours) {
  EfgSettings settings;
  settings.spacing = 0.004;
  settings.neighbours = neighbours;
  settings.cuts.push_back({Vec3(0.001, -0.1, 0.0), Vec3(0, 0.2, 0), Vec3(0, 0, 0.1)});
  const Vec3 radii(0.03, 0.02, 0.015);
  const auto inside = [radii](const Vec3& p) { return p.cwiseQuotient(radii).squaredNorm() <= 1; };
  return CorotationalEfg(inside, -radii, radii, tissue, settings);
}

class EfgMls : public testing::TestWithParam<int> {};

TEST_P(EfgMls, PartitionOfUnityAndLinearReproductionAtEveryIntegrationPoint) {
  const CorotationalEfg model = ellipsoid_model(GetParam());
  const double a = model.spacing();
  const Vector& rest = model.rest_positions();
  ASSERT_GT(model.element_count(), 100);
  double worst_sum = 0, worst_position = 0, worst_gradient_sum = 0, worst_identity = 0;
  for (int e = 0; e < model.element_count(); ++e) {
    const size_t base = static_cast<size_t>(e) * model.row_stride();
    double sum = 0;
    Vec3 position = Vec3::Zero(), gradient_sum = Vec3::Zero();
    Mat3 identity = Mat3::Zero();
    for (int k = 0; k < model.row_lengths()[e]; ++k) {
      const Vec3 particle = rest.segment<3>(3 * model.neighbours()[base + k]);
      const double phi = model.shape_values()[base + k];
      const Vec3& gradient = model.shape_gradients()[base + k];
      sum += phi;
      position += phi * (particle - model.element_centres()[e]);
      gradient_sum += gradient;
      identity += particle * gradient.transpose();
    }
    worst_sum = std::max(worst_sum, std::abs(sum - 1));
    worst_position = std::max(worst_position, position.norm() / a);
    worst_gradient_sum = std::max(worst_gradient_sum, gradient_sum.norm() * a);
    worst_identity = std::max(worst_identity, (identity - Mat3::Identity()).cwiseAbs().maxCoeff());
  }
  std::printf("MLS %d neighbours, %d elements: |sum phi - 1| %.1e, |sum phi x - x|/a %.1e, "
              "|sum grad phi| a %.1e, |sum x grad phi^T - I| %.1e\n",
              GetParam(), model.element_count(), worst_sum, worst_position, worst_gradient_sum,
              worst_identity);
  EXPECT_LT(worst_sum, 1e-10);
  EXPECT_LT(worst_position, 1e-10);
  EXPECT_LT(worst_gradient_sum, 1e-10);
  EXPECT_LT(worst_identity, 1e-10);
}

TEST_P(EfgMls, GradientsMatchFiniteDifferences) {
  const CorotationalEfg model = ellipsoid_model(GetParam());
  const double a = model.spacing();
  const Vector& rest = model.rest_positions();
  double worst = 0;
  for (int e = 0; e < model.element_count(); e += 7) {
    const size_t base = static_cast<size_t>(e) * model.row_stride();
    const int length = model.row_lengths()[e];
    std::vector<Vec3> particles;
    for (int k = 0; k < length; ++k) particles.push_back(rest.segment<3>(3 * model.neighbours()[base + k]));
    const double support = model.element_supports()[e];
    std::vector<double> plus(length), minus(length), at_centre(length);
    ASSERT_TRUE(mls_shape_functions(model.element_centres()[e], particles, support, a, at_centre, {}));
    for (int k = 0; k < length; ++k) EXPECT_DOUBLE_EQ(at_centre[k], model.shape_values()[base + k]);
    const double step = 1e-5 * a;
    for (int axis = 0; axis < 3; ++axis) {
      const Vec3 shift = step * Vec3::Unit(axis);
      ASSERT_TRUE(mls_shape_functions(model.element_centres()[e] + shift, particles, support, a, plus, {}));
      ASSERT_TRUE(mls_shape_functions(model.element_centres()[e] - shift, particles, support, a, minus, {}));
      for (int k = 0; k < length; ++k) {
        const double difference = (plus[k] - minus[k]) / (2 * step);
        worst = std::max(worst, std::abs(model.shape_gradients()[base + k][axis] - difference) * a);
      }
    }
  }
  std::printf("MLS %d neighbours: worst |grad phi - finite difference| a = %.2e\n", GetParam(), worst);
  EXPECT_LT(worst, 1e-7);
}

INSTANTIATE_TEST_SUITE_P(Neighbours, EfgMls, testing::Values(8, 4));

TEST(EfgMls, RejectsCoplanarNeighbourhoods) {
  const std::vector<Vec3> square{Vec3(0, 0, 0), Vec3(1, 0, 0), Vec3(0, 1, 0), Vec3(1, 1, 0),
                                 Vec3(2, 1, 0)};
  std::vector<double> values(square.size());
  EXPECT_FALSE(mls_shape_functions(Vec3(0.5, 0.5, 0.2), square, 10.0, 1.0, values, {}));
  EXPECT_FALSE(spans_three_dimensions(square));
  std::vector<Vec3> lifted = square;
  lifted.back().z() = 0.5;
  EXPECT_TRUE(mls_shape_functions(Vec3(0.5, 0.5, 0.2), lifted, 10.0, 1.0, values, {}));
  EXPECT_TRUE(spans_three_dimensions(lifted));
}

}  // namespace
}  // namespace incise::physics
