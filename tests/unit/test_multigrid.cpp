// The rest system's V-cycle (physics/solve/multigrid.hpp, rest_vcycle.hpp): its smoothing
// bound from the block Lanczos, symmetric and positive as CG needs, and what it saves over the
// two-level preconditioner, more with a higher Chebyshev degree.
#include "physics/core/cg.hpp"
#include "physics/core/implicit_euler.hpp"
#include "physics/efg/corotational_efg.hpp"
#include "physics/solve/block_system.hpp"
#include "physics/solve/coarse_space.hpp"
#include "physics/solve/multigrid.hpp"
#include "physics/solve/rest_preconditioner.hpp"
#include "physics/solve/rest_vcycle.hpp"

#include "tests/unit/bent_ball.hpp"

#include <gtest/gtest.h>

#include <Eigen/Geometry>

#include <cstdio>
#include <memory>
#include <vector>

namespace incise::physics {
namespace {

using fixtures::expect_symmetric_positive;
using fixtures::free_random;
using fixtures::same_bits;
using fixtures::small_efg;

// The partly fixed EFG ball of the two-level test, turned and stretched, with its step's
// system: the V-cycle's inputs as implicit_euler_step builds them.
struct TurnedBall {
  std::unique_ptr<CorotationalEfg> model = small_efg(0.002);
  Vector x;
  std::vector<std::uint8_t> fixed;
  TurnedBall() {
    const Vector& rest = model->rest_positions();
    const Eigen::Quaterniond turn(Eigen::AngleAxisd(0.4, Vec3::UnitZ()));
    x.resize(rest.size());
    for (Eigen::Index i = 0; i < rest.size() / 3; ++i)
      x.segment<3>(3 * i) = turn * Vec3(rest.segment<3>(3 * i).cwiseProduct(Vec3(1.1, 1.0, 0.95)));
    fixed.assign(static_cast<size_t>(model->node_count()), 0);
    for (int i = 0; i < model->node_count(); ++i) fixed[static_cast<size_t>(i)] = rest[3 * i + 2] < -0.015;
  }
};

// The smoothing bound's Lanczos on the block system (the rest factor's) agrees with the same
// Lanczos on the scalar matrix to round-off, fixed nodes included, and is what the factor keeps.
TEST(Multigrid, TheBlockEigenvalueEstimateIsTheScalarOne) {
  const auto model = small_efg();
  model->update_rotations(model->rest_positions());
  const BlockMatrix k = model->rest_stiffness_job()();
  std::vector<std::uint8_t> fixed(static_cast<size_t>(model->node_count()), 0);
  for (int i = 0; i < model->node_count(); i += 5) fixed[static_cast<size_t>(i)] = 1;
  const double mass_coefficient = 1.02, stiffness_coefficient = 1e-4;
  const double scalar =
      largest_jacobi_eigenvalue(k.system(model->lumped_masses(), fixed, mass_coefficient, stiffness_coefficient));
  const double blocks =
      largest_jacobi_eigenvalue(BlockSystem(k, model->lumped_masses(), fixed, mass_coefficient, stiffness_coefficient));
  EXPECT_NEAR(blocks, scalar, 1e-13 * scalar);
  EXPECT_GT(scalar, 1.0);  // Jacobi-scaled, the stiff modes lie above the diagonal's 1
  const CoarseSpace space = make_coarse_space(model->rest_positions(), 2 * model->node_spacing(), fixed);
  for (const bool single : {false, true}) {
    const RestFactor factor(k, model->lumped_masses(), fixed, mass_coefficient, stiffness_coefficient,
                            default_factor_backend(), &space, 2, single);
    EXPECT_EQ(factor.smoothing_eigenvalue(), blocks) << (single ? "float smoother" : "double smoother");
  }
}

// The V-cycle (solver.preconditioner "multigrid") is a valid CG preconditioner: symmetric,
// x^T M^-1 y = y^T M^-1 x, and positive, x^T M^-1 x > 0, for random vectors on the free
// degrees of freedom, with the rotations of a turned body in its warp.
TEST(Multigrid, TheVcycleIsSymmetricAndPositive) {
  TurnedBall ball;
  CorotationalEfg& model = *ball.model;
  model.update_rotations(ball.x);
  const double dt = 0.01, mass_coefficient = 1.0, stiffness_coefficient = dt * dt;
  const LinearOperator apply = [&](const Vector& p, Vector& out) {
    out = mass_coefficient * p;
    for (int i = 0; i < model.node_count(); ++i) out.segment<3>(3 * i) *= model.lumped_masses()[i];
    Vector stiffness = Vector::Zero(p.size());
    model.add_stiffness_product(p, stiffness);
    out += stiffness_coefficient * stiffness;
  };
  Vector diagonal = Vector::Zero(ball.x.size());
  model.add_stiffness_diagonal(diagonal);
  for (int i = 0; i < model.node_count(); ++i)
    diagonal.segment<3>(3 * i) = mass_coefficient * model.lumped_masses()[i] * Vec3::Ones() +
                                 stiffness_coefficient * diagonal.segment<3>(3 * i);
  const CoarseSpace space = make_coarse_space(model.rest_positions(), 2 * model.node_spacing(), ball.fixed);
  model.update_rotations(model.rest_positions());
  const RestFactor factor(model.rest_stiffness_job()(), model.lumped_masses(), ball.fixed, mass_coefficient,
                          stiffness_coefficient, default_factor_backend(), &space, 3);
  const RestFactor single(model.rest_stiffness_job()(), model.lumped_masses(), ball.fixed, mass_coefficient,
                          stiffness_coefficient, default_factor_backend(), &space, 3, true);
  model.update_rotations(ball.x);
  ASSERT_GT(factor.smoothing_eigenvalue(), 1.0);  // D^-1 A has unit mean diagonal: its top is above 1
  std::vector<Eigen::Quaterniond> rotations;
  model.node_rotations(rotations);
  ChebyshevSmoother smoother;
  smoother.degree = 3;
  smoother.upper = 1.2 * factor.smoothing_eigenvalue();
  VcyclePreconditioner vcycle(apply, jacobi_inverse(diagonal), factor, rotations, ball.fixed, smoother);
  expect_symmetric_positive(vcycle, ball.fixed, 1e-10);
  for (unsigned seed = 1; seed <= 5; ++seed) {
    // A smooth vector too (the coarse grid's part): a rigid translation of the free nodes.
    Vector smooth = Vector::Zero(ball.x.size());
    for (int i = 0; i < model.node_count(); ++i)
      if (!ball.fixed[static_cast<size_t>(i)]) smooth.segment<3>(3 * i) = Vec3(1, 0.5 * seed, -0.3);
    Vector msmooth(ball.x.size());
    vcycle(smooth, msmooth);
    EXPECT_GT(smooth.dot(msmooth), 0.0) << "seed " << seed;
  }
  // The cycle the implicit step runs (`multigrid`): the rest system's, on its block products
  // and its own diagonal, warped as a whole (RestVcycle), symmetric and positive likewise, with
  // the smoother's copy of A0 in double and in float. In double it has the bits of the
  // unfused cycle of A0 between the warps, R VcyclePreconditioner(A0)(R^T r).
  smoother.upper = 1.05 * factor.smoothing_eigenvalue();
  const LinearOperator rest_apply = [&](const Vector& p, Vector& out) { factor.rest_product(p, out, serial_executor()); };
  VcyclePreconditioner rest_cycle(rest_apply, factor.rest_inverse_diagonal(), factor, {}, factor.rest_fixed(), smoother);
  RestVcycle fused(factor, rotations, smoother, serial_executor());
  const Eigen::Index nodes = ball.x.size() / 3;
  for (unsigned seed = 1; seed <= 3; ++seed) {
    const Vector r = free_random(ball.fixed, seed);
    Vector turned(r.size()), rest_z(r.size()), unfused(r.size()), z(r.size());
    for (Eigen::Index i = 0; i < nodes; ++i)
      turned.segment<3>(3 * i) = rotations[static_cast<size_t>(i)].conjugate() * Vec3(r.segment<3>(3 * i));
    rest_cycle(turned, rest_z);
    for (Eigen::Index i = 0; i < nodes; ++i)
      unfused.segment<3>(3 * i) = rotations[static_cast<size_t>(i)] * Vec3(rest_z.segment<3>(3 * i));
    fused(r, z);
    EXPECT_TRUE(same_bits(z, unfused)) << "seed " << seed;
  }
  for (const RestFactor* cycle_factor : {&factor, &single}) {
    RestVcycle cycle(*cycle_factor, rotations, smoother, serial_executor());
    expect_symmetric_positive(cycle, ball.fixed, 1e-10, cycle_factor == &single ? "float" : "double");
  }
}

// CG with the V-cycle reaches the Jacobi CG's solution, to the tolerance, in far fewer
// iterations than Jacobi and than the additive two-level on the same coarse space.
TEST(Multigrid, TheVcycleCgReachesTheJacobiSolutionInFewerIterationsThanTwoLevel) {
  TurnedBall ball;
  CorotationalEfg& model = *ball.model;
  State state{ball.x, Vector::Zero(ball.x.size())};
  ImplicitEulerSettings settings;
  settings.dt = 0.01;
  settings.cg.tolerance = 1e-8;
  settings.cg.max_iterations = 2000;
  const Vector gravity = gravity_forces(model.lumped_masses(), Vec3(0, 0, -9.81));
  State jacobi_state = state;
  const StepReport jacobi = implicit_euler_step(model, jacobi_state, ball.fixed, gravity, {}, settings);
  const CoarseSpace space = make_coarse_space(model.rest_positions(), 2 * model.node_spacing(), ball.fixed);
  model.update_rotations(model.rest_positions());
  const BlockMatrix stiffness = model.rest_stiffness_job()();
  const RestFactor coarse(stiffness, model.lumped_masses(), ball.fixed, 1.0, settings.dt * settings.dt,
                          default_factor_backend(), &space);
  State two_level_state = state;
  const StepReport two_level = implicit_euler_step(model, two_level_state, ball.fixed, gravity, {}, settings, nullptr, &coarse);
  for (int degree : {1, 2, 3}) {
    const RestFactor cycle(stiffness, model.lumped_masses(), ball.fixed, 1.0, settings.dt * settings.dt,
                           default_factor_backend(), &space, degree);
    State multigrid_state = state;
    const StepReport multigrid =
        implicit_euler_step(model, multigrid_state, ball.fixed, gravity, {}, settings, nullptr, &cycle);
    ASSERT_TRUE(jacobi.cg.converged);
    ASSERT_TRUE(multigrid.cg.converged) << "degree " << degree;
    EXPECT_LT(multigrid.cg.iterations, two_level.cg.iterations) << "degree " << degree;
    const double moved = (jacobi_state.positions - ball.x).cwiseAbs().maxCoeff();
    EXPECT_LE((multigrid_state.positions - jacobi_state.positions).cwiseAbs().maxCoeff(), 1e-5 * moved);
    std::printf("CG iterations: jacobi %d, two_level %d, multigrid (degree %d) %d\n", jacobi.cg.iterations,
                two_level.cg.iterations, degree, multigrid.cg.iterations);
  }
}

// The current system's cycle (solver.preconditioner "multigrid_current", whose degree
// engine::multigrid_smoothing_degree makes 4) needs fewer iterations at degree 4 than at 2 and
// reaches the Jacobi CG's solution at both, as the rest system's does. (Uncut, as here, both
// gain alike; while cutting the current one gains far more, its smoother not lagging the cuts:
// docs/status.md.)
TEST(Multigrid, AHigherDegreeCutsTheIterationsOfBothCycles) {
  TurnedBall ball;
  CorotationalEfg& model = *ball.model;
  ImplicitEulerSettings settings;
  settings.dt = 0.01;
  settings.cg.tolerance = 1e-8;
  settings.cg.max_iterations = 2000;
  const Vector gravity = gravity_forces(model.lumped_masses(), Vec3(0, 0, -9.81));
  const State state{ball.x, Vector::Zero(ball.x.size())};
  State jacobi_state = state;
  const StepReport jacobi = implicit_euler_step(model, jacobi_state, ball.fixed, gravity, {}, settings);
  ASSERT_TRUE(jacobi.cg.converged);
  const double moved = (jacobi_state.positions - ball.x).cwiseAbs().maxCoeff();
  const CoarseSpace space = make_coarse_space(model.rest_positions(), 2 * model.node_spacing(), ball.fixed);
  model.update_rotations(model.rest_positions());
  const BlockMatrix stiffness = model.rest_stiffness_job()();
  int iterations[2][2] = {};  // [rest, current][degree 2, 4]
  for (int degree : {2, 4}) {
    const RestFactor cycle(stiffness, model.lumped_masses(), ball.fixed, 1.0, settings.dt * settings.dt,
                           default_factor_backend(), &space, degree);
    for (int current : {0, 1}) {
      settings.assembled_system = current == 1;
      State solved = state;
      const StepReport report = implicit_euler_step(model, solved, ball.fixed, gravity, {}, settings, nullptr, &cycle);
      ASSERT_TRUE(report.cg.converged) << "degree " << degree << (current ? " current" : " rest");
      EXPECT_LE((solved.positions - jacobi_state.positions).cwiseAbs().maxCoeff(), 1e-5 * moved);
      iterations[current][degree / 2 - 1] = report.cg.iterations;
    }
  }
  EXPECT_LT(iterations[0][1], iterations[0][0]);
  EXPECT_LT(iterations[1][1], iterations[1][0]);
  std::printf("CG iterations, degree 2 / 4: rest %d / %d, current %d / %d\n", iterations[0][0], iterations[0][1],
              iterations[1][0], iterations[1][1]);
}

}  // namespace
}  // namespace incise::physics
