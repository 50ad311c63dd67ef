// The multigrid's coarse space (physics/solve/coarse_space.hpp, galerkin.hpp): the trilinear
// functions of a grid twice the node spacing, a partition of unity on the free nodes, split
// where a cut divides a support or hides nodes from a vertex, their Galerkin system in blocks,
// and what the two-level preconditioner gains over Jacobi.
#include "physics/core/cg.hpp"
#include "physics/core/implicit_euler.hpp"
#include "physics/efg/corotational_efg.hpp"
#include "physics/solve/block_system.hpp"
#include "physics/solve/coarse_space.hpp"
#include "physics/solve/galerkin.hpp"
#include "physics/solve/multigrid.hpp"
#include "physics/solve/rest_preconditioner.hpp"

#include "tests/unit/bent_ball.hpp"

#include <gtest/gtest.h>

#include <Eigen/Eigenvalues>
#include <Eigen/Geometry>
#include <Eigen/Sparse>

#include <cstdio>
#include <memory>
#include <vector>

namespace incise::physics {
namespace {

using fixtures::small_efg;
using fixtures::tissue;

// The embedded coarse grid: a partition of unity on the free nodes it reaches (so translations
// are exact), nothing on fixed nodes, and a Galerkin system that factors (full column rank).
TEST(CoarseSpace, IsAPartitionOfUnityOnTheFreeNodesAndLeavesTheFixedOnesOut) {
  auto model = small_efg();
  std::vector<std::uint8_t> fixed(static_cast<size_t>(model->node_count()), 0);
  for (size_t i = 0; i < fixed.size(); i += 7) fixed[i] = 1;
  const CoarseSpace space = make_coarse_space(model->rest_positions(), 2 * model->node_spacing(), fixed);
  ASSERT_GT(space.coarse_nodes, 0);
  EXPECT_LT(space.coarse_nodes, model->node_count() / 3);
  const Vector ones = Vector::Ones(3 * space.coarse_nodes);
  const Vector row_sums = space.prolongation * ones;
  int reached = 0;
  for (int node = 0; node < model->node_count(); ++node) {
    for (int k = 0; k < 3; ++k) {
      const double sum = row_sums[3 * node + k];
      if (fixed[static_cast<size_t>(node)]) {
        EXPECT_EQ(sum, 0.0);
      } else if (sum != 0.0) {
        EXPECT_NEAR(sum, 1.0, 1e-12);
        reached += k == 0;
      }
    }
  }
  EXPECT_GT(reached, model->node_count() * 3 / 4);
  model->update_rotations(model->rest_positions());
  const RestFactor coarse(model->rest_stiffness_job()(), model->lumped_masses(), fixed, 1.0, 1e-4,
                          default_factor_backend(), &space);
  EXPECT_TRUE(coarse.coarse());
  EXPECT_EQ(coarse.factored_size(), 3 * space.coarse_nodes);
}

// The coarse space's per-node weights are its prolongation: P = W (x) I3.
TEST(CoarseSpace, ItsNodeWeightsAreTheProlongation) {
  auto model = small_efg();
  std::vector<std::uint8_t> fixed(static_cast<size_t>(model->node_count()), 0);
  for (size_t i = 0; i < fixed.size(); i += 7) fixed[i] = 1;
  const CoarseSpace space = make_coarse_space(model->rest_positions(), 2 * model->node_spacing(), fixed);
  ASSERT_EQ(space.weight_start.size(), static_cast<size_t>(model->node_count()) + 1);
  std::vector<Eigen::Triplet<double>> triplets;
  for (int node = 0; node < model->node_count(); ++node) {
    const int first = space.weight_start[static_cast<size_t>(node)], last = space.weight_start[static_cast<size_t>(node) + 1];
    EXPECT_LE(last - first, 8);
    if (fixed[static_cast<size_t>(node)]) {
      EXPECT_EQ(first, last);
    }
    for (int k = first; k < last; ++k) {
      const CoarseWeight& w = space.weights[static_cast<size_t>(k)];
      if (k > first) {
        EXPECT_GT(w.vertex, space.weights[static_cast<size_t>(k) - 1].vertex);
      }
      for (int axis = 0; axis < 3; ++axis) triplets.emplace_back(3 * node + axis, 3 * w.vertex + axis, w.weight);
    }
  }
  Eigen::SparseMatrix<double> rebuilt(space.prolongation.rows(), space.prolongation.cols());
  rebuilt.setFromTriplets(triplets.begin(), triplets.end());
  EXPECT_EQ((rebuilt - space.prolongation).norm(), 0.0);
}

// The ball of the Galerkin test below, cut halfway through by a plane (its nodes' neighbourhoods
// re-selected by visibility), its bottom fixed.
std::unique_ptr<CorotationalEfg> half_cut_ball() {
  EfgSettings settings;
  settings.spacing = 0.0025;
  settings.cuts.push_back({Vec3(-0.03, -0.03, 0.0013), Vec3(0.06, 0, 0), Vec3(0, 0.03, 0)});
  return std::make_unique<CorotationalEfg>([](const Vec3& p) { return p.norm() < 0.021; }, Vec3::Constant(-0.025),
                                           Vec3::Constant(0.025), tissue, settings);
}

std::vector<std::uint8_t> fixed_bottom(const DeformableModel& model) {
  std::vector<std::uint8_t> fixed(static_cast<size_t>(model.node_count()), 0);
  for (int node = 0; node < model.node_count(); ++node) fixed[static_cast<size_t>(node)] = model.rest_positions()[3 * node + 2] < -0.015;
  return fixed;
}

// The columns of P whose nodes the stiffness's nonzero blocks do not connect among themselves
// (a breadth-first search inside each column's nodes).
int disconnected_columns(const CoarseSpace& space, const BlockMatrix& k) {
  std::vector<std::vector<int>> column_nodes(static_cast<size_t>(space.coarse_nodes));
  for (size_t node = 0; node + 1 < space.weight_start.size(); ++node)
    for (int w = space.weight_start[node]; w < space.weight_start[node + 1]; ++w)
      column_nodes[static_cast<size_t>(space.weights[static_cast<size_t>(w)].vertex)].push_back(static_cast<int>(node));
  std::vector<int> mark(static_cast<size_t>(k.nodes()), -1);
  int disconnected = 0;
  for (int column = 0; column < space.coarse_nodes; ++column) {
    const std::vector<int>& nodes = column_nodes[static_cast<size_t>(column)];
    if (nodes.empty()) continue;
    for (int node : nodes) mark[static_cast<size_t>(node)] = column;
    std::vector<int> queue{nodes.front()};
    mark[static_cast<size_t>(nodes.front())] = -2 - column;  // reached
    for (size_t next = 0; next < queue.size(); ++next)
      for (int b = k.row_start()[static_cast<size_t>(queue[next])]; b < k.row_start()[static_cast<size_t>(queue[next]) + 1]; ++b) {
        const int other = k.columns()[static_cast<size_t>(b)];
        if (mark[static_cast<size_t>(other)] == column && (k.blocks()[static_cast<size_t>(b)].array() != 0).any()) {
          mark[static_cast<size_t>(other)] = -2 - column;
          queue.push_back(other);
        }
      }
    disconnected += queue.size() < nodes.size();
    for (int node : nodes) mark[static_cast<size_t>(node)] = -1;
  }
  return disconnected;
}

// P's rows sum to one on the free nodes a column reaches, to zero on the fixed ones.
void expect_partition_of_unity_where_reached(const CoarseSpace& space, const std::vector<std::uint8_t>& fixed) {
  const Vector row_sums = space.prolongation * Vector::Ones(3 * space.coarse_nodes);
  for (size_t node = 0; node < fixed.size(); ++node) {
    const double sum = row_sums[3 * static_cast<Eigen::Index>(node)];
    if (fixed[node]) {
      EXPECT_EQ(sum, 0.0);
    } else if (sum != 0.0) {
      EXPECT_NEAR(sum, 1.0, 1e-12) << "node " << node;
    }
  }
}

// Given the cut body's stiffness, the coarse space splits each vertex whose support the cut
// divides: every column's nodes connected through the stiffness (the plain grid has columns
// across the cut), still a partition of unity on the free nodes it reaches, with more columns;
// an uncut ball's space is the plain one bit for bit.
TEST(CoarseSpace, ACutSplitsTheVerticesWhoseSupportItDivides) {
  {
    const auto uncut = small_efg(0.0025);
    uncut->update_rotations(uncut->rest_positions());
    const std::vector<std::uint8_t> fixed = fixed_bottom(*uncut);
    const BlockMatrix k = uncut->rest_stiffness_job()();
    const CoarseSpace plain = make_coarse_space(uncut->rest_positions(), 2 * uncut->node_spacing(), fixed);
    const CoarseSpace coupled = make_coarse_space(uncut->rest_positions(), 2 * uncut->node_spacing(), fixed, &k);
    ASSERT_EQ(coupled.coarse_nodes, plain.coarse_nodes);
    EXPECT_EQ((coupled.prolongation - plain.prolongation).norm(), 0.0);
    EXPECT_EQ(disconnected_columns(plain, k), 0);
  }
  const auto model = half_cut_ball();
  model->update_rotations(model->rest_positions());
  const std::vector<std::uint8_t> fixed = fixed_bottom(*model);
  const BlockMatrix k = model->rest_stiffness_job()();
  const CoarseSpace plain = make_coarse_space(model->rest_positions(), 2 * model->node_spacing(), fixed);
  const CoarseSpace split = make_coarse_space(model->rest_positions(), 2 * model->node_spacing(), fixed, &k);
  const int across = disconnected_columns(plain, k);
  EXPECT_GE(across, 5);  // 7 of 104
  EXPECT_EQ(disconnected_columns(split, k), 0);
  EXPECT_GT(split.coarse_nodes, plain.coarse_nodes);
  expect_partition_of_unity_where_reached(split, fixed);
  std::printf("coarse space of the half-cut ball: %d columns across the cut of %d; split: %d columns\n", across,
              plain.coarse_nodes, split.coarse_nodes);
}

// half_cut_ball's cut as the coarse space asks it: the rectangle z = 0.0013, -0.03 <= x <= 0.03,
// -0.03 <= y <= 0 (a plane test of its own, not the cut module's).
constexpr double cut_z = 0.0013;
bool in_cut_rectangle(double x, double y) { return x >= -0.03 && x <= 0.03 && y >= -0.03 && y <= 0.0; }
CutSeparation half_cut_separation() {
  CutSeparation separation;
  separation.near = [](const Vec3& lo, const Vec3& hi) {
    return lo.z() <= cut_z && hi.z() >= cut_z && lo.x() <= 0.03 && hi.x() >= -0.03 && lo.y() <= 0.0 && hi.y() >= -0.03;
  };
  separation.crosses = [](const Vec3& a, const Vec3& b) {
    if ((a.z() - cut_z) * (b.z() - cut_z) > 0 || a.z() == b.z()) return false;
    const Vec3 at = a + (cut_z - a.z()) / (b.z() - a.z()) * (b - a);
    return in_cut_rectangle(at.x(), at.y());
  };
  return separation;
}

// The columns of P that hold two nodes facing each other across the cut (both over the cut's
// rectangle, within a node spacing of its plane on either side): a coarse function that ties
// the lips together.
int columns_across_the_lips(const CoarseSpace& space, const Vector& rest, double spacing) {
  std::vector<int> side(static_cast<size_t>(space.coarse_nodes), 0);  // bit 1: a node above, bit 2: below
  int across = 0;
  for (size_t node = 0; node + 1 < space.weight_start.size(); ++node) {
    const Vec3 p = rest.segment<3>(3 * static_cast<Eigen::Index>(node));
    if (!in_cut_rectangle(p.x(), p.y()) || std::abs(p.z() - cut_z) > spacing) continue;
    for (int w = space.weight_start[node]; w < space.weight_start[node + 1]; ++w)
      side[static_cast<size_t>(space.weights[static_cast<size_t>(w)].vertex)] |= p.z() > cut_z ? 1 : 2;
  }
  for (int s : side) across += s == 3;
  return across;
}

// Given the cut itself, a vertex does not lean on the nodes it does not see across the cut:
// where the cut's front leaves the support connected around it (the coupling alone keeps one
// function there, tying the lips together), those nodes take a copy of their own or, holding
// half a weight at most (here all of them: nodes midway between vertices), lean on their other
// corners alone. Still a partition of unity on the free nodes it reaches, of full rank; a cut
// that no support meets changes nothing.
TEST(CoarseSpace, AVertexLeavesTheNodesTheCutHidesFromIt) {
  const auto model = half_cut_ball();
  model->update_rotations(model->rest_positions());
  const Vector& rest = model->rest_positions();
  const std::vector<std::uint8_t> fixed = fixed_bottom(*model);
  const BlockMatrix k = model->rest_stiffness_job()();
  const double spacing = 2 * model->node_spacing();
  const CutSeparation separation = half_cut_separation();
  const CoarseSpace split = make_coarse_space(rest, spacing, fixed, &k);
  const CoarseSpace seen = make_coarse_space(rest, spacing, fixed, &k, &separation);
  const int tied = columns_across_the_lips(split, rest, model->node_spacing());
  const int tied_seen = columns_across_the_lips(seen, rest, model->node_spacing());
  EXPECT_GE(tied, 5);
  EXPECT_LT(tied_seen, tied);
  EXPECT_GE(seen.coarse_nodes, split.coarse_nodes);
  EXPECT_EQ(disconnected_columns(seen, k), 0);
  const Eigen::SparseMatrix<double> gram = seen.prolongation.transpose() * seen.prolongation;
  EXPECT_GT(Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd>(Eigen::MatrixXd(gram)).eigenvalues().minCoeff(), 1e-6);
  expect_partition_of_unity_where_reached(seen, fixed);
  CutSeparation elsewhere;
  elsewhere.near = [](const Vec3&, const Vec3&) { return false; };
  elsewhere.crosses = [](const Vec3&, const Vec3&) { return true; };
  const CoarseSpace unseen = make_coarse_space(rest, spacing, fixed, &k, &elsewhere);
  ASSERT_EQ(unseen.coarse_nodes, split.coarse_nodes);
  EXPECT_EQ((unseen.prolongation - split.prolongation).norm(), 0.0);
  std::printf("half-cut ball: %d columns hold both lips split by the coupling (of %d), %d split by what the vertices see (of %d)\n",
              tied, split.coarse_nodes, tied_seen, seen.coarse_nodes);
}

// A cut through a layer of nodes (the blade drawn exactly along particles, as a replay's may
// be): those nodes lie on the cut, behind it from no vertex, and the space keeps full column
// rank (P^T P positive definite), so the Galerkin system factors. Two vertices that each saw
// such a node alone across the cut would have given it two identical columns.
TEST(CoarseSpace, NodesOnTheCutKeepTheSpaceOfFullRank) {
  const auto model = half_cut_ball();
  model->update_rotations(model->rest_positions());
  const Vector& rest = model->rest_positions();
  const std::vector<std::uint8_t> fixed = fixed_bottom(*model);
  const BlockMatrix k = model->rest_stiffness_job()();
  // The layer of nodes nearest z = 0.
  double layer = 1.0;
  for (int node = 0; node < model->node_count(); ++node)
    if (std::abs(rest[3 * node + 2]) < std::abs(layer)) layer = rest[3 * node + 2];
  CutSeparation on_layer;
  on_layer.near = [layer](const Vec3& lo, const Vec3& hi) { return lo.z() <= layer && hi.z() >= layer; };
  on_layer.crosses = [layer](const Vec3& a, const Vec3& b) {
    if ((a.z() - layer) * (b.z() - layer) > 0 || a.z() == b.z()) return false;
    const Vec3 at = a + (layer - a.z()) / (b.z() - a.z()) * (b - a);
    return in_cut_rectangle(at.x(), at.y());
  };
  const CoarseSpace space = make_coarse_space(rest, 2 * model->node_spacing(), fixed, &k, &on_layer);
  const Eigen::SparseMatrix<double> gram = space.prolongation.transpose() * space.prolongation;
  const Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> spectrum{Eigen::MatrixXd(gram)};
  EXPECT_GT(spectrum.eigenvalues().minCoeff(), 1e-6);
  EXPECT_NO_THROW(RestFactor(k, model->lumped_masses(), fixed, 1.0, 1e-4, default_factor_backend(), &space, 2));
  std::printf("half-cut ball cut through its node layer z = %.4f: %d columns, the smallest eigenvalue of P^T P %.3g\n",
              layer, space.coarse_nodes, spectrum.eigenvalues().minCoeff());
}

// On the half-cut ball hanging from its fixed bottom, the two-level preconditioner and the
// V-cycle with the split coarse space reach the same step in fewer CG iterations than with the
// plain grid, whose functions tie the cut's lips together.
TEST(CoarseSpace, TheSplitSpaceSavesIterationsOnACutBody) {
  const auto model = half_cut_ball();
  const Vector& rest = model->rest_positions();
  const std::vector<std::uint8_t> fixed = fixed_bottom(*model);
  model->update_rotations(rest);
  const BlockMatrix k = model->rest_stiffness_job()();
  ImplicitEulerSettings settings;
  settings.dt = 0.01;
  settings.cg.tolerance = 1e-8;
  settings.cg.max_iterations = 2000;
  const Vector gravity = gravity_forces(model->lumped_masses(), Vec3(0, 0, -9.81));
  const State start{rest, Vector::Zero(rest.size())};
  const CoarseSpace plain = make_coarse_space(rest, 2 * model->node_spacing(), fixed);
  const CoarseSpace split = make_coarse_space(rest, 2 * model->node_spacing(), fixed, &k);
  const CutSeparation separation = half_cut_separation();
  const CoarseSpace seen = make_coarse_space(rest, 2 * model->node_spacing(), fixed, &k, &separation);
  const CoarseSpace* spaces[3] = {&plain, &split, &seen};
  for (const int smoothing : {0, 2}) {
    int iterations[3] = {0, 0, 0};
    Vector positions[3];
    for (int which = 0; which < 3; ++which) {
      const RestFactor factor(k, model->lumped_masses(), fixed, 1.0, settings.dt * settings.dt, default_factor_backend(),
                              spaces[which], smoothing);
      State state = start;
      const StepReport report = implicit_euler_step(*model, state, fixed, gravity, {}, settings, nullptr, &factor);
      ASSERT_TRUE(report.cg.converged) << "smoothing " << smoothing << (which == 0 ? " plain" : " split");
      iterations[which] = report.cg.iterations;
      positions[which] = state.positions;
    }
    EXPECT_LT(iterations[1], iterations[0]) << "smoothing " << smoothing;
    EXPECT_LE(iterations[2], iterations[1]) << "smoothing " << smoothing;
    const double moved = (positions[0] - rest).cwiseAbs().maxCoeff();
    EXPECT_LE((positions[1] - positions[0]).cwiseAbs().maxCoeff(), 1e-5 * moved);
    EXPECT_LE((positions[2] - positions[0]).cwiseAbs().maxCoeff(), 1e-5 * moved);
    std::printf("half-cut ball, %s: CG iterations %d with the plain coarse grid, %d split by the coupling, %d by what the vertices see\n",
                smoothing == 0 ? "two_level" : "multigrid (degree 2)", iterations[0], iterations[1], iterations[2]);
  }
}

// The Galerkin coarse system from the blocks (galerkin.hpp) is Eigen's P^T (A0 P) of the
// scalar system, on a ball cut halfway through (re-selected neighbourhoods, an uneven pattern)
// with fixed nodes: the same lower triangle, pattern and entries.
TEST(Galerkin, TheBlockProductEqualsEigensOnACutBodyWithFixedNodes) {
  EfgSettings settings;
  settings.spacing = 0.0025;
  settings.cuts.push_back({Vec3(-0.03, -0.03, 0.0013), Vec3(0.06, 0, 0), Vec3(0, 0.03, 0)});
  CorotationalEfg model([](const Vec3& p) { return p.norm() < 0.021; }, Vec3::Constant(-0.025), Vec3::Constant(0.025),
                        tissue, settings);
  model.update_rotations(model.rest_positions());
  std::vector<std::uint8_t> fixed(static_cast<size_t>(model.node_count()), 0);
  for (int node = 0; node < model.node_count(); ++node)
    if (model.rest_positions()[3 * node + 2] < -0.012 || node % 11 == 0) fixed[static_cast<size_t>(node)] = 1;
  const BlockMatrix k = model.rest_stiffness_job()();
  const double mass_coefficient = 1.02, stiffness_coefficient = 1e-4;
  const CoarseSpace space = make_coarse_space(model.rest_positions(), 2 * model.node_spacing(), fixed);
  const Eigen::SparseMatrix<double> scalar = k.system(model.lumped_masses(), fixed, mass_coefficient, stiffness_coefficient);
  const Eigen::SparseMatrix<double> product =
      Eigen::SparseMatrix<double>(space.prolongation.transpose()) * (scalar * space.prolongation);
  const Eigen::SparseMatrix<double> reference = product.triangularView<Eigen::Lower>();
  const Eigen::SparseMatrix<double> lower =
      galerkin_lower(k, model.lumped_masses(), fixed, mass_coefficient, stiffness_coefficient, space);
  ASSERT_EQ(lower.rows(), 3 * space.coarse_nodes);
  ASSERT_EQ(lower.cols(), 3 * space.coarse_nodes);
  ASSERT_EQ(lower.nonZeros(), reference.nonZeros());
  for (int column = 0; column < lower.outerSize(); ++column) {
    Eigen::SparseMatrix<double>::InnerIterator it(lower, column), expected(reference, column);
    for (; it && expected; ++it, ++expected) ASSERT_EQ(it.index(), expected.index()) << "column " << column;
    EXPECT_FALSE(it || expected) << "column " << column;
  }
  const double largest = reference.coeffs().cwiseAbs().maxCoeff();
  const Eigen::SparseMatrix<double> difference = lower - reference;
  EXPECT_LE(difference.coeffs().cwiseAbs().maxCoeff(), 1e-13 * largest);
  std::printf("galerkin: %d coarse nodes, %lld lower entries, max |difference| %.3g of max |entry| %.3g\n",
              space.coarse_nodes, static_cast<long long>(lower.nonZeros()),
              difference.coeffs().cwiseAbs().maxCoeff(), largest);
}

// Jacobi plus the coarse correction (two_level) reaches the Jacobi CG's solution in fewer
// iterations on a partly fixed EFG ball (about 10 particles across), turned and stretched.
TEST(CoarseSpace, TheTwoLevelPreconditionerNeedsFewerIterationsThanJacobiForTheSameSolution) {
  auto model = small_efg(0.002);
  const Vector& rest = model->rest_positions();
  const Eigen::Quaterniond turn(Eigen::AngleAxisd(0.4, Vec3::UnitZ()));
  Vector x(rest.size());
  for (Eigen::Index i = 0; i < rest.size() / 3; ++i)
    x.segment<3>(3 * i) = turn * Vec3(rest.segment<3>(3 * i).cwiseProduct(Vec3(1.1, 1.0, 0.95)));
  std::vector<std::uint8_t> fixed(static_cast<size_t>(model->node_count()), 0);
  for (int i = 0; i < model->node_count(); ++i) fixed[static_cast<size_t>(i)] = rest[3 * i + 2] < -0.015;
  State state{x, Vector::Zero(rest.size())};
  ImplicitEulerSettings settings;
  settings.dt = 0.01;
  settings.cg.tolerance = 1e-8;
  settings.cg.max_iterations = 2000;
  const Vector gravity = gravity_forces(model->lumped_masses(), Vec3(0, 0, -9.81));
  State jacobi_state = state;
  const StepReport jacobi = implicit_euler_step(*model, jacobi_state, fixed, gravity, {}, settings);
  const CoarseSpace space = make_coarse_space(rest, 2 * model->node_spacing(), fixed);
  const RestFactor coarse(model->rest_stiffness_job()(), model->lumped_masses(), fixed, 1.0, settings.dt * settings.dt,
                          default_factor_backend(), &space);
  State two_level_state = state;
  const StepReport two_level = implicit_euler_step(*model, two_level_state, fixed, gravity, {}, settings, nullptr, &coarse);
  ASSERT_TRUE(jacobi.cg.converged);
  ASSERT_TRUE(two_level.cg.converged);
  EXPECT_LT(two_level.cg.iterations, jacobi.cg.iterations * 3 / 4);
  const double moved = (jacobi_state.positions - x).cwiseAbs().maxCoeff();
  EXPECT_LE((two_level_state.positions - jacobi_state.positions).cwiseAbs().maxCoeff(), 1e-5 * moved);
  std::printf("CG iterations: jacobi %d, two_level %d\n", jacobi.cg.iterations, two_level.cg.iterations);
}

}  // namespace
}  // namespace incise::physics
