// Baudet's correction forces in the implicit step's matrix (issue 31): the extra stiffness the
// mass-spring gives the step against finite differences of the corrections, and a dt = 10 s
// (quasi-static) step sequence against the network's static solve (physics/mss/mss_static.hpp,
// Newton with the full tangent): with the corrections' full derivative (BiCGSTAB) the steps
// reach the same equilibrium to 1e-6 in the fewest steps, their symmetric part in the CG in as
// many or more, the corrections explicit in more still, or never (they diverge at nu 0.45).
#include "physics/core/implicit_euler.hpp"
#include "physics/mss/hex_mass_spring.hpp"
#include "physics/mss/hex_mesh.hpp"
#include "physics/mss/mss_static.hpp"

#include <gtest/gtest.h>

#include <Eigen/Dense>

#include <cstdio>
#include <random>
#include <vector>

namespace physics = incise::physics;
using physics::CorrectionTangent;
using physics::Vec3;
using physics::Vector;

namespace {

physics::MassSpringMaterial corrected(double nu, CorrectionTangent tangent) {
  physics::MassSpringMaterial m{1e4, nu, 1500, 1};  // the report's test material (Fléchon §5.3)
  m.corrections = true;
  m.correction_tangent = tangent;
  return m;
}

// A 3 x 2 x 1 block stretched 10 % along x, sheared and jittered: every brick's corrections
// and their derivative away from rest.
Vector deformed(const physics::HexMesh& mesh) {
  std::mt19937 random(11);
  std::uniform_real_distribution<double> jitter(-0.004, 0.004);
  Vector x = mesh.rest;
  for (Eigen::Index i = 0; i < x.size() / 3; ++i) {
    x[3 * i] *= 1.1;
    x[3 * i + 1] += 0.05 * x[3 * i + 2];
  }
  for (Eigen::Index i = 0; i < x.size(); ++i) x[i] += jitter(random);
  return x;
}

}  // namespace

TEST(MassSpringImplicit, TheExtraStiffnessIsTheCorrectionsDerivative) {
  const physics::HexMesh mesh = physics::make_box_hexes(Vec3::Zero(), {0.3, 0.2, 0.1}, {3, 2, 1});
  physics::HexMassSpring full(mesh, corrected(0.3, CorrectionTangent::full));
  physics::HexMassSpring symmetric(mesh, corrected(0.3, CorrectionTangent::symmetric));
  physics::HexMassSpring none(mesh, corrected(0.3, CorrectionTangent::explicit_forces));
  const Vector x = deformed(mesh);
  for (auto* model : {&full, &symmetric, &none}) model->update_rotations(x);
  EXPECT_TRUE(full.has_extra_stiffness());
  EXPECT_FALSE(full.extra_stiffness_symmetric());
  EXPECT_TRUE(symmetric.extra_stiffness_symmetric());
  EXPECT_FALSE(none.has_extra_stiffness());
  const Eigen::Index size = x.size();
  // Column by column from the products, against -d(corrections)/dx by central differences of
  // the whole force vector with a step 100 times the model's own.
  Eigen::MatrixXd k_full(size, size), k_symmetric(size, size), numeric(size, size);
  const double h = 1e-5 * 0.1;
  for (Eigen::Index d = 0; d < size; ++d) {
    Vector unit = Vector::Zero(size), column = Vector::Zero(size);
    unit[d] = 1;
    full.add_extra_stiffness_product(unit, column);
    k_full.col(d) = column;
    column.setZero();
    symmetric.add_extra_stiffness_product(unit, column);
    k_symmetric.col(d) = column;
    Vector plus = x, minus = x, fp = Vector::Zero(size), fm = Vector::Zero(size);
    plus[d] += h, minus[d] -= h;
    full.add_correction_forces(plus, fp);
    full.add_correction_forces(minus, fm);
    numeric.col(d) = -(fp - fm) / (2 * h);
  }
  EXPECT_GT(numeric.norm(), 0);
  EXPECT_LT((k_full - numeric).norm(), 1e-6 * numeric.norm());
  // Not symmetric (the corrections are no potential's gradient), and the symmetric variant is its symmetric part.
  EXPECT_GT((numeric - numeric.transpose()).norm(), 1e-2 * numeric.norm());
  EXPECT_LT((k_symmetric - 0.5 * (k_full + k_full.transpose())).norm(), 1e-12 * k_full.norm());
  Vector diagonal = Vector::Zero(size);
  full.add_extra_stiffness_diagonal(diagonal);
  EXPECT_LT((diagonal - k_full.diagonal()).norm(), 1e-12 * diagonal.norm());
  // Rows sum to zero: the corrections' derivative keeps momentum (a translation changes nothing).
  Vector translation(size), moved = Vector::Zero(size);
  for (Eigen::Index i = 0; i < size / 3; ++i) translation.segment<3>(3 * i) = Vec3(1, -2, 0.5);
  full.add_extra_stiffness_product(translation, moved);
  EXPECT_LT(moved.norm(), 1e-6 * k_full.norm());
  // With the corrections explicit the model has none.
  Vector nothing = Vector::Zero(size);
  none.add_extra_stiffness_product(translation, nothing);
  EXPECT_EQ(nothing.norm(), 0);
}

namespace {

struct Quasistatic {
  int steps = -1;         // steps to within the tolerance of the static solve; -1: not in the budget
  double last_error = 0;  // relative, at the last step taken
  int krylov = 0;         // CG or BiCGSTAB iterations, all steps together
  double tip = 0;         // the static solve's largest displacement, m
};

// A clamped 4 x 2 x 2 bar of 0.1 m cubes (E 1e4, rho 1500) under gravity `gravity` by
// implicit Euler steps of dt = 10 s from rest, against the static solve: the error is the
// largest node distance over the static solve's largest displacement.
Quasistatic quasistatic(CorrectionTangent tangent, double nu, double gravity, int budget, double tolerance) {
  const physics::HexMesh mesh = physics::make_box_hexes(Vec3::Zero(), {0.4, 0.2, 0.2}, {4, 2, 2});
  physics::HexMassSpring model(mesh, corrected(nu, tangent));
  std::vector<std::uint8_t> fixed(static_cast<std::size_t>(model.node_count()), 0);
  for (int i = 0; i < model.node_count(); ++i) fixed[static_cast<std::size_t>(i)] = mesh.rest[3 * i] < 1e-9;
  const Vector load = physics::gravity_forces(model.lumped_masses(), Vec3(0, 0, -gravity));
  physics::HexMassSpring reference_model(mesh, corrected(nu, tangent));
  const physics::MassSpringStatic reference =
      physics::solve_mass_spring_static(reference_model, fixed, Vector(), load, 8, 1e-12);
  double largest = 0;
  for (int i = 0; i < model.node_count(); ++i)
    largest = std::max(largest, (reference.positions - mesh.rest).segment<3>(3 * i).norm());
  physics::State state{mesh.rest, Vector::Zero(mesh.rest.size())};
  physics::ImplicitEulerSettings settings;
  settings.dt = 10;
  settings.cg.tolerance = 1e-12;
  settings.cg.max_iterations = 5000;
  Quasistatic result;
  result.tip = largest;
  for (int step = 1; step <= budget; ++step) {
    const physics::StepReport report = physics::implicit_euler_step(model, state, fixed, load, {}, settings);
    if (report.nonfinite) return result;  // (the explicit corrections diverge at nu 0.45)
    result.krylov += report.cg.iterations;
    double error = 0;
    for (int i = 0; i < model.node_count(); ++i)
      error = std::max(error, (state.positions - reference.positions).segment<3>(3 * i).norm());
    result.last_error = error / largest;
    if (result.last_error < tolerance) {
      result.steps = step;
      return result;
    }
  }
  return result;
}

}  // namespace

TEST(MassSpringImplicit, LargeStepsReachTheStaticEquilibrium) {
  // nu 0.1 (c_ij > 0) under a load that bends the 0.4 m bar's tip down 0.22 m, and nu 0.45
  // (c_ij < 0, the largest) under a quarter of it (0.046 m).
  for (const auto& [nu, gravity] : {std::pair{0.1, 1.6}, std::pair{0.45, 0.4}}) {
    const Quasistatic full = quasistatic(CorrectionTangent::full, nu, gravity, 40, 1e-6);
    const Quasistatic symmetric = quasistatic(CorrectionTangent::symmetric, nu, gravity, 40, 1e-6);
    const Quasistatic none = quasistatic(CorrectionTangent::explicit_forces, nu, gravity, 40, 1e-6);
    std::printf("nu %g, g %g m/s^2 (static tip %.3g m), dt = 10 s: steps to 1e-6 of the static solve (Krylov iterations; "
                "BiCGSTAB's take two products each), error at the last step\n"
                "  full K_c (BiCGSTAB) %d (%d) %.3g; symmetric part (CG) %d (%d) %.3g; explicit %d (%d) %.3g\n",
                nu, gravity, full.tip, full.steps, full.krylov, full.last_error, symmetric.steps, symmetric.krylov,
                symmetric.last_error, none.steps, none.krylov, none.last_error);
    ASSERT_GT(full.steps, 0) << "nu " << nu;
    EXPECT_LE(full.steps, 15) << "nu " << nu;
    EXPECT_GE(symmetric.steps, full.steps) << "nu " << nu;
    EXPECT_TRUE(none.steps < 0 || none.steps > full.steps) << "nu " << nu;
  }
}
