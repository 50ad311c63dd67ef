// The V-cycle on the assembled current system (physics/solve/current_vcycle.hpp): the rest
// factor's bound still above the current spectrum, the node-block scaling and what it saves,
// the combined warm start, the cycle symmetric, positive and convergent, its coarse transfers
// and its fused passes bit for bit against their references on any threads.
#include "physics/core/implicit_euler.hpp"
#include "physics/efg/corotational_efg.hpp"
#include "physics/solve/coarse_transfer.hpp"
#include "physics/solve/current_system.hpp"
#include "physics/solve/current_vcycle.hpp"
#include "physics/solve/jacobi_scaling.hpp"
#include "physics/solve/multigrid.hpp"
#include "physics/solve/paired_blocks.hpp"
#include "physics/solve/warped_preconditioner.hpp"

#include "tests/unit/bent_ball.hpp"
#include "tests/unit/test_executors.hpp"

#include <gtest/gtest.h>

#include <Eigen/Geometry>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <memory>
#include <random>
#include <thread>

namespace incise::physics {
namespace {

using fixtures::BallRun;
using fixtures::ball_factor;
using fixtures::BentBall;
using fixtures::current_cycle_settings;
using fixtures::expect_symmetric_positive;
using fixtures::free_random;
using fixtures::random_vector;
using fixtures::same_bits;
using test::ShufflingExecutor;
using test::TwoThreadExecutor;


// The smoother's interval ends at 1.2 x the rest build's estimate of D0^-1 A0's largest
// eigenvalue (implicit_euler.cpp); the current D^-1 A of the bent, turned body stays below it.
TEST(CurrentSystem, TheRestSmoothingBoundCoversTheCurrentSpectrum) {
  BentBall ball;
  CorotationalEfg& model = *ball.model;
  const double mass_coefficient = 1.0, stiffness_coefficient = 1e-4;
  model.update_rotations(model.rest_positions());
  const BlockMatrix rest = model.rest_stiffness_job()();
  const double rest_top =
      largest_jacobi_eigenvalue(rest.system(model.lumped_masses(), ball.fixed, mass_coefficient, stiffness_coefficient));
  model.update_rotations(ball.x);
  const BlockMatrix& current = *model.current_stiffness();
  const double current_top = largest_jacobi_eigenvalue(
      current.system(model.lumped_masses(), ball.fixed, mass_coefficient, stiffness_coefficient), 80);
  std::printf("largest eigenvalue of D^-1 A: rest %.4f, bent and turned %.4f\n", rest_top, current_top);
  EXPECT_LT(current_top, 1.2 * rest_top);
  // With A's node blocks for D (jacobi_scaling.hpp) the top barely moves: a block turns with
  // its node, so the smoother's margin over the rest estimate can be small.
  const double rest_block_top = largest_block_jacobi_eigenvalue(
      BlockSystem(rest, model.lumped_masses(), ball.fixed, mass_coefficient, stiffness_coefficient));
  const double current_block_top = largest_block_jacobi_eigenvalue(
      BlockSystem(current, model.lumped_masses(), ball.fixed, mass_coefficient, stiffness_coefficient), 80);
  std::printf("largest eigenvalue of B^-1 A: rest %.4f, bent and turned %.4f\n", rest_block_top, current_block_top);
  EXPECT_LT(current_block_top, 1.02 * rest_block_top);
  EXPECT_GT(current_block_top, 0.9 * rest_block_top);
}

// The node blocks' scaling is the inverse of each block: B (B^-1 r) = r node by node; a block
// that is not positive definite falls back to its diagonal's inverse (1 for a non-positive
// entry), as jacobi_inverse does.
TEST(CurrentSystem, TheNodeBlockScalingInvertsEachBlock) {
  BentBall ball;
  CorotationalEfg& model = *ball.model;
  model.update_rotations(ball.x);
  const CurrentSystem system(*model.current_stiffness(), model.lumped_masses(), ball.fixed, {}, 1.0, 1e-4);
  const std::vector<Mat3> blocks = system.diagonal_blocks();
  const Vector diagonal = system.diagonal();
  const JacobiScaling scaling = JacobiScaling::node_blocks(blocks);
  const Vector r = random_vector(diagonal.size(), 9);
  Vector scaled(r.size());
  scaling.apply(r.data(), scaled.data(), 0, r.size());
  for (int node = 0; node < system.nodes(); ++node) {
    const Mat3& block = blocks[static_cast<size_t>(node)];
    ASSERT_EQ(block.diagonal(), Vec3(diagonal.segment<3>(3 * node))) << "node " << node;  // the diagonal's bits
    EXPECT_LE((block * Vec3(scaled.segment<3>(3 * node)) - Vec3(r.segment<3>(3 * node))).norm(),
              1e-12 * r.segment<3>(3 * node).norm()) << "node " << node;
  }
  Mat3 indefinite = Mat3::Identity();
  indefinite(0, 1) = indefinite(1, 0) = 2.0;  // eigenvalues -1, 3, 1
  Mat3 negative = Mat3::Identity();
  negative(2, 2) = -4.0;
  const JacobiScaling fallback = JacobiScaling::node_blocks({indefinite, negative});
  const double ones[6] = {1, 1, 1, 1, 1, 1};
  double out[6];
  fallback.apply(ones, out, 0, 6);
  EXPECT_EQ(out[0], 1.0);
  EXPECT_EQ(out[1], 1.0);
  EXPECT_EQ(out[2], 1.0);
  EXPECT_EQ(out[5], 1.0);  // -4 is not a positive entry
}

// A current-cycle factor (node blocks) estimates B0^-1 A0's top alone and keeps no copy of A0:
// it serves no rest cycle. A step that does not assemble the current system (here the
// settings', as for a damped body) falls back to Jacobi with it, to the current cycle's
// solution; a diagonal-scaled factor's rest cycle gets there too.
TEST(CurrentSystem, ACurrentCycleFactorServesNoRestCycle) {
  BentBall ball;
  CorotationalEfg& model = *ball.model;
  const ImplicitEulerSettings current = current_cycle_settings(1e-8);
  ImplicitEulerSettings matrix_free = current;
  matrix_free.assembled_system = false;
  const std::unique_ptr<RestFactor> blocks = ball_factor(ball, current.dt, true);
  const std::unique_ptr<RestFactor> diagonal = ball_factor(ball, current.dt, false);
  EXPECT_GT(blocks->node_block_eigenvalue(), 0.0);
  EXPECT_EQ(blocks->smoothing_eigenvalue(), 0.0);
  EXPECT_EQ(blocks->rest_system().nodes(), 0);
  EXPECT_FALSE(blocks->serves_rest_cycles());
  EXPECT_GT(diagonal->smoothing_eigenvalue(), 0.0);
  EXPECT_TRUE(diagonal->serves_rest_cycles());
  EXPECT_TRUE(assembles_current_stiffness(model));
  const Vector load = gravity_forces(model.lumped_masses(), Vec3(20, 0, -9.81));
  const auto step = [&](const ImplicitEulerSettings& settings, const RestFactor& factor) {
    State state{ball.x, Vector::Zero(ball.x.size())};
    const StepReport report = implicit_euler_step(model, state, ball.fixed, load, {}, settings, nullptr, &factor);
    EXPECT_TRUE(report.cg.converged);
    return std::make_pair(report.cg.iterations, state.positions);
  };
  const auto [cycle_iterations, cycle] = step(current, *blocks);
  const auto [fallback_iterations, fallback] = step(matrix_free, *blocks);
  const auto [rest_iterations, rest] = step(matrix_free, *diagonal);
  const double moved = (cycle - ball.x).cwiseAbs().maxCoeff();
  EXPECT_LE((fallback - cycle).cwiseAbs().maxCoeff(), 1e-5 * moved);
  EXPECT_LE((rest - cycle).cwiseAbs().maxCoeff(), 1e-5 * moved);
  // Jacobi's iterations, well above either cycle's.
  EXPECT_GT(fallback_iterations, 2 * rest_iterations);
  EXPECT_GT(fallback_iterations, 2 * cycle_iterations);
  std::printf("bent ball, one step: %d CG iterations on the current cycle, %d on the rest cycle, %d on Jacobi\n",
              cycle_iterations, rest_iterations, fallback_iterations);
}

// On the bent ball stepped by the engine's path (the current V-cycle of degree 4), scaling the
// smoother by the node blocks takes fewer CG iterations than by the diagonal, to the same
// solution.
TEST(CurrentSystem, TheNodeBlockSmootherSavesIterations) {
  const ImplicitEulerSettings settings = current_cycle_settings(1e-8);
  const auto run = [&](bool node_blocks) {
    BentBall ball;
    CorotationalEfg& model = *ball.model;
    const std::unique_ptr<RestFactor> factor = ball_factor(ball, settings.dt, node_blocks);
    EXPECT_EQ(factor->node_block_eigenvalue() > 0, node_blocks);
    State state{ball.x, Vector::Zero(ball.x.size())};
    BallRun result;
    for (int step = 0; step < 5; ++step) {
      const Vector load = gravity_forces(model.lumped_masses(), Vec3(20, 0, -9.81));
      const StepReport report = implicit_euler_step(model, state, ball.fixed, load, {}, settings, nullptr, factor.get());
      EXPECT_TRUE(report.cg.converged) << "step " << step;
      result.iterations += report.cg.iterations;
    }
    result.positions = state.positions;
    return result;
  };
  const BallRun diagonal = run(false), blocks = run(true);
  const double moved = (diagonal.positions - BentBall().x).cwiseAbs().maxCoeff();
  std::printf("bent ball, 5 steps from rest: %d CG iterations with the diagonal's scaling, %d with the node blocks'\n",
              diagonal.iterations, blocks.iterations);
  EXPECT_LT(blocks.iterations, diagonal.iterations);
  EXPECT_LE((blocks.positions - diagonal.positions).cwiseAbs().maxCoeff(), 1e-5 * moved);
}

// The ball, from rest, follows a load that turns slowly, stepped as the engine steps it (the
// scene's tolerance, assembled system, the current V-cycle): from the combination of the last four dv
// (warm_start.hpp) CG needs fewer iterations in all than from the newest dv alone, and the
// two runs reach the same state to the solver's tolerance.
TEST(CurrentSystem, TheCombinedWarmStartSavesIterationsOfTheVcycle) {
  const ImplicitEulerSettings settings = current_cycle_settings(1e-5);
  const auto run = [&](int depth) {
    BentBall ball;
    CorotationalEfg& model = *ball.model;
    const std::unique_ptr<RestFactor> factor = ball_factor(ball, settings.dt);
    State state{model.rest_positions(), Vector::Zero(ball.x.size())};
    WarmStart start(depth);
    BallRun result;
    for (int step = 0; step < 30; ++step) {
      const double angle = 0.05 * step;
      const Vector load = gravity_forces(model.lumped_masses(), Vec3(30 * std::cos(angle), 30 * std::sin(angle), -9.81));
      const StepReport report = implicit_euler_step(model, state, ball.fixed, load, {}, settings, &start, factor.get());
      EXPECT_TRUE(report.cg.converged) << "step " << step;
      result.iterations += report.cg.iterations;
    }
    result.positions = state.positions;
    return result;
  };
  const BallRun newest = run(1), combined = run(WarmStart::default_depth);
  const double moved = (newest.positions - BentBall().model->rest_positions()).cwiseAbs().maxCoeff();
  std::printf("ball, 30 steps: %d CG iterations from the newest dv, %d from the combination of %d; moved %.3e m\n",
              newest.iterations, combined.iterations, WarmStart::default_depth, moved);
  EXPECT_LT(combined.iterations, newest.iterations);
  EXPECT_LT((combined.positions - newest.positions).cwiseAbs().maxCoeff(), 1e-3 * moved);
}

// The implicit step on the assembled system with the current V-cycle reaches the Jacobi CG's
// solution in a few times fewer iterations; the cycle itself is symmetric and positive on the
// free degrees of freedom.
TEST(CurrentSystem, TheCurrentVcycleIsSymmetricPositiveAndConverges) {
  BentBall ball;
  CorotationalEfg& model = *ball.model;
  ImplicitEulerSettings settings;
  settings.dt = 0.01;
  settings.cg.tolerance = 1e-8;
  settings.cg.max_iterations = 3000;
  const Vector gravity = gravity_forces(model.lumped_masses(), Vec3(0, 0, -9.81));
  const CoarseSpace space = make_coarse_space(model.rest_positions(), 2 * model.node_spacing(), ball.fixed);
  model.update_rotations(model.rest_positions());
  const RestFactor factor(model.rest_stiffness_job()(), model.lumped_masses(), ball.fixed, 1.0, settings.dt * settings.dt,
                          default_factor_backend(), &space, 2);
  const State start{ball.x, Vector::Zero(ball.x.size())};
  State jacobi = start, rest = start, current = start;
  const StepReport jacobi_report = implicit_euler_step(model, jacobi, ball.fixed, gravity, {}, settings);
  const StepReport rest_report = implicit_euler_step(model, rest, ball.fixed, gravity, {}, settings, nullptr, &factor);
  settings.assembled_system = true;
  const StepReport current_report = implicit_euler_step(model, current, ball.fixed, gravity, {}, settings, nullptr, &factor);
  ASSERT_TRUE(jacobi_report.cg.converged);
  ASSERT_TRUE(rest_report.cg.converged);
  ASSERT_TRUE(current_report.cg.converged);
  EXPECT_LT(current_report.cg.iterations, jacobi_report.cg.iterations / 3);
  const double moved = (jacobi.positions - ball.x).cwiseAbs().maxCoeff();
  EXPECT_LE((current.positions - jacobi.positions).cwiseAbs().maxCoeff(), 1e-5 * moved);
  std::printf("CG iterations: jacobi %d, multigrid %d, multigrid_current %d\n", jacobi_report.cg.iterations,
              rest_report.cg.iterations, current_report.cg.iterations);

  // The cycle as current_vcycle_solve builds it.
  model.update_rotations(ball.x);
  const CurrentSystem system(*model.current_stiffness(), model.lumped_masses(), ball.fixed, {}, 1.0,
                             settings.dt * settings.dt);
  const LinearOperator apply = [&](const Vector& p, Vector& out) { system.multiply(p, out, serial_executor()); };
  std::vector<Eigen::Quaterniond> rotations;
  model.node_rotations(rotations);
  ChebyshevSmoother smoother;
  smoother.degree = 2;
  smoother.upper = 1.2 * factor.smoothing_eigenvalue();
  VcyclePreconditioner vcycle(apply, jacobi_inverse(system.diagonal()), factor, rotations, ball.fixed, smoother);
  expect_symmetric_positive(vcycle, ball.fixed, 1e-10, "double cycle");
  // The fused cycle on K's paired float copy, as the step runs it (degree 4): symmetric to
  // float round-off (its operands and sums are rounded), positive, and within the float
  // rounding's reach of the double cycle.
  smoother.degree = 4;
  for (const bool node_blocks : {false, true}) {
  smoother.node_blocks = node_blocks;
  CurrentVcycle single(system, factor, rotations, smoother, serial_executor(), CycleEntries::single);
  CurrentVcycle dual(system, factor, rotations, smoother, serial_executor());
  expect_symmetric_positive(single, ball.fixed, 1e-6, node_blocks ? "node blocks" : "diagonal");
  for (unsigned seed = 1; seed <= 5; ++seed) {
    const Vector x = free_random(ball.fixed, seed);
    Vector mx, mx_double;
    single(x, mx);
    dual(x, mx_double);
    EXPECT_FALSE(same_bits(mx, mx_double));
    EXPECT_LE((mx - mx_double).norm(), 1e-5 * mx_double.norm()) << "seed " << seed;
  }
  }
}

// The coarse transfers as row-wise gathers have the bits of Eigen's sparse products on P.
TEST(CurrentSystem, TheCoarseTransfersHaveTheBitsOfTheSparseProducts) {
  BentBall ball;
  const CorotationalEfg& model = *ball.model;
  const CoarseSpace space = make_coarse_space(model.rest_positions(), 2 * model.node_spacing(), ball.fixed);
  const CoarseTransfer transfer(space.prolongation);
  ASSERT_EQ(transfer.nodes(), model.node_count());
  ASSERT_EQ(transfer.coarse_nodes(), space.coarse_nodes);
  const Vector t = random_vector(space.prolongation.rows(), 3), u = random_vector(space.prolongation.cols(), 4);
  const Vector restricted = space.prolongation.transpose() * t, prolonged = space.prolongation * u;
  Vector gathered(u.size()), spread(t.size());
  transfer.restrict_nodes(t.data(), gathered.data(), 0, transfer.coarse_nodes());
  for (int node = 0; node < transfer.nodes(); ++node) spread.segment<3>(3 * node) = transfer.prolong_node(u.data(), node);
  EXPECT_TRUE(same_bits(gathered, restricted));
  EXPECT_TRUE(same_bits(spread, prolonged));
  // Not blocks w I: refused.
  Eigen::SparseMatrix<double> skewed = space.prolongation;
  skewed.makeCompressed();
  skewed.valuePtr()[skewed.outerIndexPtr()[1]] *= 2;  // column 1's first weight: no longer column 0's
  EXPECT_THROW(CoarseTransfer{skewed}, std::invalid_argument);
}

// The fused cycle the implicit step runs (CurrentVcycle) has the bits of VcyclePreconditioner
// on the same system, factor and rotations, on one thread, two, and ranges handed out in any
// order; with smoothers of degree 1 to 4, a spring, and no warp; on K's blocks in double, in
// their paired float copy and with the smoother on its halves (then the bits of the V-cycle
// with those products).
TEST(CurrentSystem, TheFusedCurrentVcycleHasTheBitsOfTheVcycleOnAnyThreads) {
  BentBall ball;
  CorotationalEfg& model = *ball.model;
  const double mass_coefficient = 1.0, stiffness_coefficient = 1e-4;
  const CoarseSpace space = make_coarse_space(model.rest_positions(), 2 * model.node_spacing(), ball.fixed);
  model.update_rotations(model.rest_positions());
  const RestFactor factor(model.rest_stiffness_job()(), model.lumped_masses(), ball.fixed, mass_coefficient,
                          stiffness_coefficient, default_factor_backend(), &space, 4);
  model.update_rotations(ball.x);
  const NodalSpring spring{7, Vec3::Zero(), Mat3::Identity() * 50.0 + Mat3::Constant(3.0)};
  const CurrentSystem system(*model.current_stiffness(), model.lumped_masses(), ball.fixed,
                             std::span<const NodalSpring>(&spring, 1), mass_coefficient, stiffness_coefficient);
  // The rounded cycles' products are the paired float products of p on the single or half
  // entries (their D stays the double system's).
  const PairedBlocks paired(system.rows(), system.nodes(), serial_executor(), true);
  std::vector<float> operand(paired.operand_size(), 0.0f);
  const LinearOperator apply = [&](const Vector& p, Vector& out) { system.multiply(p, out, serial_executor()); };
  const auto apply_rounded = [&](PairedPrecision precision) -> LinearOperator {
    return [&, precision](const Vector& p, Vector& out) {
      PairedBlocks::round_operand(system.rows(), p.data(), operand.data(), 0, system.nodes());
      out.resize(p.size());
      paired.multiply_rows(system.rows(), p.data(), operand.data(), out.data(), 0, system.nodes(), precision);
    };
  };
  std::vector<Eigen::Quaterniond> rotations;
  model.node_rotations(rotations);
  const std::vector<Eigen::Quaterniond> none;
  TwoThreadExecutor two;
  ShufflingExecutor shuffling;
  for (int degree = 1; degree <= 4; ++degree)
    for (const CycleEntries entries : {CycleEntries::double_precision, CycleEntries::single, CycleEntries::half_smoother})
    for (const bool node_blocks : {false, true}) {
    ChebyshevSmoother smoother;
    smoother.degree = degree;
    smoother.upper = 1.2 * factor.smoothing_eigenvalue();
    smoother.node_blocks = node_blocks;
    const JacobiScaling scaling = node_blocks ? JacobiScaling::node_blocks(system.diagonal_blocks())
                                              : JacobiScaling(jacobi_inverse(system.diagonal()));
    for (const std::vector<Eigen::Quaterniond>* warp : std::array<const std::vector<Eigen::Quaterniond>*, 2>{&rotations, &none}) {
      const LinearOperator product = entries == CycleEntries::double_precision ? apply
                                     : apply_rounded(entries == CycleEntries::single ? PairedPrecision::single
                                                                                      : PairedPrecision::half);
      VcyclePreconditioner reference(product, scaling, factor, *warp, ball.fixed, smoother);
      CurrentVcycle one_thread(system, factor, *warp, smoother, serial_executor(), entries);
      CurrentVcycle two_threads(system, factor, *warp, smoother, two, entries);
      CurrentVcycle shuffled(system, factor, *warp, smoother, shuffling, entries);
      for (unsigned seed = 1; seed <= 2; ++seed) {
        const Vector r = random_vector(ball.x.size(), seed);  // nonzero on the fixed nodes too
        Vector expected, z1, z2, z3;
        reference(r, expected);
        one_thread(r, z1);
        two_threads(r, z2);
        shuffled(r, z3);
        const std::string where = "degree " + std::to_string(degree) + " entries " + std::to_string(static_cast<int>(entries)) +
                                  (node_blocks ? " node blocks" : " diagonal") +
                                  (warp->empty() ? " unwarped" : " warped") +
                                  " seed " + std::to_string(seed);
        ASSERT_TRUE(expected.allFinite()) << where;
        EXPECT_TRUE(same_bits(z1, expected)) << where;
        EXPECT_TRUE(same_bits(z2, expected)) << where;
        EXPECT_TRUE(same_bits(z3, expected)) << where;
      }
    }
  }
}

}  // namespace
}  // namespace incise::physics
