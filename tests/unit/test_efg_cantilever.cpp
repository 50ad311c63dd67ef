// Benchmark B1 with the EFG model: the cantilever under its own weight (x in [0, 0.2] m,
// y, z in [-0.01, 0.01] m, clamped at x = 0, E = 10 MPa, nu = 0.3, rho = 1000, g along -z).
// The thesis's hypothesis H1 asks for less than 10 % error against FEM with 8 neighbours
// (seed-004 §5.6); the issue asks for 3 % at the test's resolution.
#include "physics/core/implicit_euler.hpp"
#include "physics/efg/corotational_efg.hpp"
#include "physics/efg/efg_static.hpp"
#include "physics/fem/static_solve.hpp"
#include "physics/fem/tet_mesh.hpp"

#include <gtest/gtest.h>

#include <chrono>
#include <cmath>
#include <cstdio>

namespace incise::physics {
namespace {

const Material beam_material{10e6, 0.3, 1000};
const Vec3 beam_min(0.0, -0.01, -0.01), beam_max(0.2, 0.01, 0.01);
const Vec3 gravity(0, 0, -9.81);

// The mean z displacement over the tip face (x = 0.2) in mm, from a 10 x 10 grid of cell
// centres of the face moved with the MLS embedding.
double efg_tip_mm(const CorotationalEfg& model, const Vector& displacements) {
  const int side = 10;
  Vector points(3 * side * side);
  for (int j = 0; j < side; ++j) {
    for (int i = 0; i < side; ++i) {
      points.segment<3>(3 * (i + side * j)) =
          Vec3(beam_max.x(), beam_min.y() + (i + 0.5) * 0.02 / side, beam_min.z() + (j + 0.5) * 0.02 / side);
    }
  }
  const SurfaceEmbedding embedding = model.embed_surface(points);
  Vector moved;
  CorotationalEfg::surface_positions(embedding, model.rest_positions() + displacements, moved);
  double sum = 0;
  for (int v = 0; v < side * side; ++v) sum += moved[3 * v + 2] - points[3 * v + 2];
  return -1e3 * sum / (side * side);
}

// The quadratic-tet reference (20 x 4 x 4 cells, converged to 0.1 % per the FEM tests):
// mean z displacement of the tip nodes, in mm.
double reference_tip_mm() {
  const QuadraticTetMesh mesh = make_box_quadratic_tets(beam_min, beam_max, {20, 4, 4});
  const Vector u = solve_static_quadratic(
      mesh, beam_material, nodes_in_box(mesh.rest, Vec3::Constant(-1), Vec3(1e-12, 1, 1)),
      beam_material.density * gravity);
  double sum = 0;
  int count = 0;
  for (Eigen::Index node = 0; node < mesh.rest.size() / 3; ++node) {
    if (std::abs(mesh.rest[3 * node] - beam_max.x()) < 1e-12) {
      sum += u[3 * node + 2];
      ++count;
    }
  }
  return -1e3 * sum / count;
}

struct EfgSolve {
  double tip_mm = 0;
  int dofs = 0;
};

EfgSolve solve_efg(double spacing, int neighbours, double support_factor) {
  EfgSettings settings;
  settings.spacing = spacing;
  settings.neighbours = neighbours;
  settings.support_factor = support_factor;
  CorotationalEfg model(beam_min, beam_max, beam_material, settings);
  model.update_rotations(model.rest_positions());
  const Vector load = gravity_forces(model.lumped_masses(), gravity);
  // Particles on the clamped face are fixed (MLS does not interpolate, seed-004 §1.7).
  const std::vector<uint8_t> clamped =
      nodes_in_box(model.rest_positions(), Vec3::Constant(-1), Vec3(1e-12, 1, 1));
  const Vector u = solve_static(assemble_stiffness(model), load, clamped);
  return {efg_tip_mm(model, u), 3 * model.node_count()};
}

TEST(EfgCantileverB1, StaticTipDeflectionAgainstQuadraticTets) {
  const double reference = reference_tip_mm();
  std::printf("B1 reference (10-node tets 20x4x4): tip %.4f mm (beam theory 5.947 mm)\n", reference);
  const auto error_of = [&](double spacing, int neighbours, double support_factor) {
    const EfgSolve solve = solve_efg(spacing, neighbours, support_factor);
    const double error = std::abs(solve.tip_mm / reference - 1);
    std::printf("B1 EFG a = %.4f m, %d neighbours, support factor %.4f, %d dofs: tip %.4f mm, "
                "error %.2f %%\n",
                spacing, neighbours, support_factor, solve.dofs, solve.tip_mm, 100 * error);
    return error;
  };
  // The default (8 neighbours, h = 1.1 x the farthest corner, 2.86 a at a cube's centre): within 1 % at both
  // sizes (seed-004 §5.1: 0.4 % in bending at about 10k dofs).
  EXPECT_LT(error_of(0.005, 8, EfgSettings{}.support_factor), 0.01);
  EXPECT_LT(error_of(0.0025, 8, EfgSettings{}.support_factor), 0.01);
  // The literal reading h = 3 x the farthest neighbour: hypothesis H1, < 10 %, and converging,
  // but its flat weights leave the cells' hourglass-like modes little stiffness, so the coarse
  // beam is far too soft.
  const double coarse = error_of(0.005, 8, 3.0);
  const double fine = error_of(0.0025, 8, 3.0);
  EXPECT_GT(coarse, 0.10);
  EXPECT_LT(fine, 0.10);
  EXPECT_LT(fine, coarse / 3);
  // h = 1.2 x farthest neighbour, near the default, also meets the 3 %.
  EXPECT_LT(error_of(0.0025, 8, 1.2), 0.03);
  // 4 neighbours interpolate linearly on a corner tetrahedron, which locks in bending like a
  // linear tet: too stiff.
  EXPECT_LT(error_of(0.0025, 4, 3.0), 0.25);
}

TEST(EfgCantileverB1, ImplicitEulerSettlesToTheStaticSolution) {
  EfgSettings settings;
  settings.spacing = 0.005;
  CorotationalEfg model(beam_min, beam_max, beam_material, settings);
  const std::vector<uint8_t> clamped =
      nodes_in_box(model.rest_positions(), Vec3::Constant(-1), Vec3(1e-12, 1, 1));
  const Vector weight = gravity_forces(model.lumped_masses(), gravity);
  model.update_rotations(model.rest_positions());
  const double static_tip =
      efg_tip_mm(model, solve_static(assemble_stiffness(model), weight, clamped));

  State state{model.rest_positions(), Vector::Zero(model.rest_positions().size())};
  ImplicitEulerSettings integrator;
  // Large steps and strong damping: the equilibrium, not the motion, is under test.
  integrator.dt = 0.05;
  integrator.rayleigh_mass = 40;
  integrator.cg.tolerance = 1e-8;
  integrator.cg.max_iterations = 2000;
  const auto start = std::chrono::steady_clock::now();
  double tip = 0, previous = 0;
  int steps = 0, iterations = 0;
  for (; steps < 200; ++steps) {
    const StepReport report = implicit_euler_step(model, state, clamped, weight, {}, integrator);
    ASSERT_FALSE(report.nonfinite) << "step " << steps;
    ASSERT_TRUE(report.cg.converged) << "step " << steps;
    iterations += report.cg.iterations;
    previous = tip;
    tip = efg_tip_mm(model, state.positions - model.rest_positions());
    if (steps > 5 && std::abs(tip - previous) < 1e-6 * std::abs(tip)) break;
  }
  const std::chrono::duration<double> elapsed = std::chrono::steady_clock::now() - start;
  std::printf("B1 EFG dynamic a = 0.005: tip %.4f mm after %d steps, %d CG iterations (%.2f s), "
              "static %.4f mm\n",
              tip, steps, iterations, elapsed.count(), static_tip);
  // Corotation makes the dynamic equilibrium differ from the linear static one by the
  // geometric non-linearity only (tip rotation about 0.04 rad here).
  EXPECT_NEAR(tip / static_tip, 1.0, 0.01);
}

}  // namespace
}  // namespace incise::physics
