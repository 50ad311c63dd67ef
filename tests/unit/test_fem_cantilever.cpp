// Benchmark B1: a cantilever under its own weight.
// Beam x in [0, 0.2] m, y, z in [-0.01, 0.01] m, clamped (every node) at x = 0, rho = 1000,
// g = 9.81 along -z, E = 10 MPa, nu = 0.3. The tip value is the mean z displacement of the
// nodes at x = 0.2. Beam theory: Euler-Bernoulli q L^4 / (8 E I) = 5.886 mm plus the
// Timoshenko shear term q L^2 / (2 kappa G A) = 0.061 mm gives 5.947 mm.
#include <gtest/gtest.h>

#include <chrono>
#include <cmath>
#include <cstdio>

#include "physics/core/implicit_euler.hpp"
#include "physics/fem/corotational_fem.hpp"
#include "physics/fem/static_solve.hpp"
#include "physics/fem/tet_mesh.hpp"

namespace incise::physics {
namespace {

const Material beam_material{10e6, 0.3, 1000};
const Vec3 beam_min(0.0, -0.01, -0.01), beam_max(0.2, 0.01, 0.01);
const Vec3 gravity(0, 0, -9.81);
const double beam_theory_tip_mm = 5.947;

std::array<int, 3> cells_for(int along) { return {along, along / 5, along / 5}; }

std::vector<uint8_t> clamped_nodes(const Vector& rest) {
  return nodes_in_box(rest, Vec3::Constant(-1), Vec3(1e-12, 1, 1));
}

// Mean z displacement of the nodes at x = 0.2, in mm.
double tip_mm(const Vector& rest, const Vector& displacements) {
  double sum = 0;
  int count = 0;
  for (Eigen::Index node = 0; node < rest.size() / 3; ++node) {
    if (std::abs(rest[3 * node] - beam_max.x()) < 1e-12) {
      sum += displacements[3 * node + 2];
      ++count;
    }
  }
  return -1e3 * sum / count;
}

struct Solve {
  double tip_mm = 0;
  double seconds = 0;
};

Solve solve_linear(int along) {
  const TetMesh mesh = make_box_tets(beam_min, beam_max, cells_for(along));
  const auto start = std::chrono::steady_clock::now();
  const Vector u = solve_static_linear(mesh, beam_material, clamped_nodes(mesh.rest),
                                       beam_material.density * gravity);
  const std::chrono::duration<double> elapsed = std::chrono::steady_clock::now() - start;
  return {tip_mm(mesh.rest, u), elapsed.count()};
}

Solve solve_quadratic(int along) {
  const QuadraticTetMesh mesh = make_box_quadratic_tets(beam_min, beam_max, cells_for(along));
  const auto start = std::chrono::steady_clock::now();
  const Vector u = solve_static_quadratic(mesh, beam_material, clamped_nodes(mesh.rest),
                                          beam_material.density * gravity);
  const std::chrono::duration<double> elapsed = std::chrono::steady_clock::now() - start;
  return {tip_mm(mesh.rest, u), elapsed.count()};
}

// The finest quadratic result, shared by the tests (computed once).
const Solve& quadratic_reference() {
  static const Solve reference = solve_quadratic(20);
  return reference;
}

TEST(CantileverB1, QuadraticTetsMatchBeamTheory) {
  const Solve coarse = solve_quadratic(10);
  const Solve& fine = quadratic_reference();
  for (const auto& [name, solve] : {std::pair{"10x2x2", coarse}, std::pair{"20x4x4", fine}}) {
    std::printf("B1 quadratic %s: tip %.4f mm, error %+.2f %% vs %.3f mm, solve %.3f s\n", name,
                solve.tip_mm, 100 * (solve.tip_mm / beam_theory_tip_mm - 1), beam_theory_tip_mm,
                solve.seconds);
  }
  EXPECT_NEAR(fine.tip_mm / beam_theory_tip_mm, 1.0, 0.02);
  EXPECT_NEAR(coarse.tip_mm / fine.tip_mm, 1.0, 0.02);  // already converged at 10x2x2
}

TEST(CantileverB1, LinearTetsConvergeAtSecondOrder) {
  const double reference = quadratic_reference().tip_mm;
  std::vector<double> errors;
  for (int along : {10, 20, 40}) {
    const Solve solve = solve_linear(along);
    errors.push_back(std::abs(solve.tip_mm / reference - 1));
    std::printf(
        "B1 linear %dx%dx%d: tip %.4f mm, error %.2f %% vs quadratic %.4f mm, solve %.3f s\n",
        along, along / 5, along / 5, solve.tip_mm, 100 * errors.back(), reference, solve.seconds);
  }
  std::printf("B1 linear error ratios: %.2f, %.2f\n", errors[0] / errors[1], errors[1] / errors[2]);
  EXPECT_GT(errors[0], errors[1]);
  EXPECT_GT(errors[1], errors[2]);
  EXPECT_GE(errors[1] / errors[2], 2.5);
}

TEST(CantileverB1, DynamicCorotationalSettlesToStaticLinear) {
  const TetMesh mesh = make_box_tets(beam_min, beam_max, cells_for(10));
  const std::vector<uint8_t> clamped = clamped_nodes(mesh.rest);
  const double static_tip = tip_mm(mesh.rest, solve_static_linear(mesh, beam_material, clamped,
                                                                  beam_material.density * gravity));

  CorotationalTetFem model(mesh, beam_material);
  State state{mesh.rest, Vector::Zero(mesh.rest.size())};
  const Vector weight = gravity_forces(model.lumped_masses(), gravity);
  ImplicitEulerSettings settings;
  settings.dt = 0.01;
  settings.rayleigh_mass = 2;
  settings.cg.tolerance = 1e-8;
  settings.cg.max_iterations = 1000;
  const auto start = std::chrono::steady_clock::now();
  int steps = 0;
  double previous = 0, tip = 0;
  for (; steps < 2000; ++steps) {
    const StepReport report = implicit_euler_step(model, state, clamped, weight, {}, settings);
    ASSERT_FALSE(report.nonfinite) << "step " << steps;
    ASSERT_TRUE(report.cg.converged) << "step " << steps;
    previous = tip;
    tip = tip_mm(mesh.rest, state.positions - mesh.rest);
    if (steps > 50 && std::abs(tip - previous) < 1e-7 * std::abs(tip)) break;
  }
  const std::chrono::duration<double> elapsed = std::chrono::steady_clock::now() - start;
  std::printf(
      "B1 dynamic corotational 10x2x2: tip %.4f mm after %d steps (%.3f s), static linear %.4f "
      "mm\n",
      tip, steps, elapsed.count(), static_tip);
  EXPECT_NEAR(tip / static_tip, 1.0, 0.01);
}

}  // namespace
}  // namespace incise::physics
