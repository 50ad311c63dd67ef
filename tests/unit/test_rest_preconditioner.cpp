// The rest-shape preconditioner (physics/solve/): the assembled K0 against the models' own
// matrix-free products, the warp exact for a rigid rotation, and which factor a step uses.
#include "physics/core/cg.hpp"
#include "physics/core/implicit_euler.hpp"
#include "physics/efg/corotational_efg.hpp"
#include "physics/fem/corotational_fem.hpp"
#include "physics/fem/tet_mesh.hpp"
#include "physics/solve/block_product.hpp"
#include "physics/solve/block_system.hpp"
#include "physics/solve/galerkin.hpp"
#include "physics/solve/multigrid.hpp"
#include "physics/solve/rest_preconditioner.hpp"
#include "physics/solve/rest_vcycle.hpp"
#include "physics/solve/warped_preconditioner.hpp"

#include "tests/unit/bent_ball.hpp"
#include "tests/unit/test_executors.hpp"

#include <gtest/gtest.h>

#include <Eigen/Eigenvalues>
#include <Eigen/Geometry>

#include <memory>
#include <cstdio>
#include <cstring>
#include <random>

namespace incise::physics {
namespace {

using fixtures::expect_symmetric_positive;
using fixtures::free_random;
using fixtures::random_vector;
using test::ShufflingExecutor;

const Material tissue{5e3, 0.45, 1060};

std::unique_ptr<CorotationalEfg> small_efg(double spacing = 0.005) {
  EfgSettings settings;
  settings.spacing = spacing;
  // A ball: partial cubes, re-selected neighbourhoods and varied rows, not only full cells.
  return std::make_unique<CorotationalEfg>(
      [](const Vec3& p) { return p.norm() < 0.021; }, Vec3::Constant(-0.025), Vec3::Constant(0.025), tissue, settings);
}

std::unique_ptr<CorotationalTetFem> small_fem() {
  return std::make_unique<CorotationalTetFem>(make_box_tets(Vec3::Zero(), Vec3(0.04, 0.02, 0.02), {4, 2, 2}), tissue);
}

// K0 p from the assembled blocks.
Vector assembled_product(const BlockMatrix& k, const Vector& p) {
  const Vector no_mass = Vector::Zero(k.nodes());
  // system() with no mass and unit stiffness coefficient is K0 itself (nothing fixed).
  return k.system(no_mass, {}, 1.0, 1.0) * p;
}

void expect_assembly_matches_product(DeformableModel& model) {
  model.update_rotations(model.rest_positions());  // every rotation the identity
  const BlockMatrix k = model.rest_stiffness_job()();
  const Vector p = random_vector(model.rest_positions().size(), 7);
  Vector matrix_free = Vector::Zero(p.size());
  model.add_stiffness_product(p, matrix_free);
  const Vector assembled = assembled_product(k, p);
  EXPECT_LE((assembled - matrix_free).norm(), 1e-12 * matrix_free.norm());
}

TEST(RestStiffness, EfgAssemblyEqualsTheMatrixFreeProductAtRest) { expect_assembly_matches_product(*small_efg()); }

TEST(RestStiffness, TetAssemblyEqualsTheMatrixFreeProductAtRest) { expect_assembly_matches_product(*small_fem()); }

// A body turned rigidly by Q: every element rotation is Q, so is every node's, and the
// corotated system is Q A0 Q^T exactly; the warped factor then solves it in one iteration.
void expect_exact_for_rigid_rotation(DeformableModel& model) {
  const Eigen::Quaterniond turn(Eigen::AngleAxisd(0.7, Vec3(1, 2, 3).normalized()));
  const Vector& rest = model.rest_positions();
  Vector turned(rest.size());
  for (Eigen::Index i = 0; i < rest.size() / 3; ++i) turned.segment<3>(3 * i) = turn * Vec3(rest.segment<3>(3 * i));
  model.update_rotations(turned);
  std::vector<Eigen::Quaterniond> rotations;
  model.node_rotations(rotations);
  ASSERT_EQ(rotations.size(), static_cast<size_t>(model.node_count()));
  for (const auto& q : rotations) EXPECT_LE(q.angularDistance(turn), 1e-9);

  const double mass_coefficient = 1.02, stiffness_coefficient = 1e-4;
  std::vector<std::uint8_t> fixed(static_cast<size_t>(model.node_count()), 0);
  fixed[0] = fixed[3] = 1;
  const RestFactor factor(model.rest_stiffness_job()(), model.lumped_masses(), fixed, mass_coefficient,
                          stiffness_coefficient);
  const LinearOperator apply = [&](const Vector& p, Vector& out) {
    out = Vector::Zero(p.size());
    model.add_stiffness_product(p, out);
    out *= stiffness_coefficient;
    for (Eigen::Index i = 0; i < p.size(); ++i) out[i] += mass_coefficient * model.lumped_masses()[i / 3] * p[i];
  };
  const Preconditioner warped = [&](const Vector& r, Vector& z) { warped_solve(factor, rotations, r, z); };
  Vector x = Vector::Zero(rest.size());
  CgSettings settings;
  settings.tolerance = 1e-10;
  const CgResult result =
      preconditioned_conjugate_gradient(apply, random_vector(rest.size(), 3), warped, fixed, x, settings);
  EXPECT_TRUE(result.converged);
  EXPECT_LE(result.iterations, 1);
  // The identity warp (the rest factor alone) is not exact for the turned body.
  Vector y = Vector::Zero(rest.size());
  const Preconditioner unwarped = [&](const Vector& r, Vector& z) { warped_solve(factor, {}, r, z); };
  EXPECT_GT(preconditioned_conjugate_gradient(apply, random_vector(rest.size(), 3), unwarped, fixed, y, settings).iterations, 3);
}

// The V-cycle's assembled rest system (block_system.hpp) is the scalar system the factor is
// built from (BlockMatrix::system), fixed rows and columns included, and its product has the
// same bits however the rows are split among threads.
TEST(BlockSystem, EqualsTheScalarSystemAndIsIndependentOfTheSplit) {
  const auto model = small_efg();
  const BlockMatrix k = model->rest_stiffness_job()();
  std::vector<std::uint8_t> fixed(static_cast<size_t>(model->node_count()), 0);
  for (int i = 0; i < model->node_count(); i += 5) fixed[static_cast<size_t>(i)] = 1;
  const double mass_coefficient = 1.02, stiffness_coefficient = 1e-4;
  const BlockSystem blocks(k, model->lumped_masses(), fixed, mass_coefficient, stiffness_coefficient);
  const Eigen::SparseMatrix<double> scalar = k.system(model->lumped_masses(), fixed, mass_coefficient, stiffness_coefficient);
  const Vector x = random_vector(3 * model->node_count(), 7);
  Vector serial, shuffled;
  blocks.multiply(x, serial, serial_executor());
  ShufflingExecutor shuffling;
  blocks.multiply(x, shuffled, shuffling);
  const Vector reference = scalar * x;
  EXPECT_LE((serial - reference).cwiseAbs().maxCoeff(), 1e-12 * reference.cwiseAbs().maxCoeff());
  EXPECT_EQ(0, std::memcmp(serial.data(), shuffled.data(), sizeof(double) * static_cast<size_t>(x.size())));
  EXPECT_EQ(blocks.diagonal(), Vector(scalar.diagonal()));
  // The residual's update is the product subtracted, bit for bit.
  Vector residual = random_vector(x.size(), 8), expected = residual - serial;
  blocks.subtract_product(x, residual, shuffling);
  EXPECT_EQ(0, std::memcmp(residual.data(), expected.data(), sizeof(double) * static_cast<size_t>(x.size())));
}

bool same_bits(const Vector& a, const Vector& b) {
  return a.size() == b.size() && std::memcmp(a.data(), b.data(), sizeof(double) * static_cast<size_t>(a.size())) == 0;
}

// The block product's AVX2 kernel (where the CPU has it) and its portable one have the same
// bits, in double and in float, and in double those of the product before them: Eigen's
// `sum += Matrix3d * x.segment<3>()` per block, summed in column order.
TEST(BlockSystem, TheVectorisedAndPortableKernelsAgreeBitForBit) {
  const auto model = small_efg();
  const BlockMatrix k = model->rest_stiffness_job()();
  std::vector<std::uint8_t> fixed(static_cast<size_t>(model->node_count()), 0);
  for (int i = 0; i < model->node_count(); i += 7) fixed[static_cast<size_t>(i)] = 1;
  const double mass_coefficient = 1.02, stiffness_coefficient = 1e-4;
  const Vector x = random_vector(3 * model->node_count(), 9);
  // The blocks as BlockSystem forms them, multiplied as it did before its kernels.
  Vector eigen_blocks(x.size());
  for (int row = 0; row < model->node_count(); ++row) {
    Eigen::Vector3d sum = Eigen::Vector3d::Zero();
    for (int b = k.row_start()[static_cast<size_t>(row)]; b < k.row_start()[static_cast<size_t>(row) + 1]; ++b) {
      const int column = k.columns()[static_cast<size_t>(b)];
      if (fixed[static_cast<size_t>(row)] != 0 && column != row) continue;
      if (fixed[static_cast<size_t>(column)] != 0 && column != row) continue;
      Mat3 block = stiffness_coefficient * k.blocks()[static_cast<size_t>(b)];
      if (column == row) block.diagonal().array() += mass_coefficient * model->lumped_masses()[row];
      if (fixed[static_cast<size_t>(row)] != 0) block = Mat3::Identity();
      sum.noalias() += block * x.segment<3>(3 * column);
    }
    eigen_blocks.segment<3>(3 * row) = sum;
  }
  for (bool single : {false, true}) {
    const BlockSystem blocks(k, model->lumped_masses(), fixed, mass_coefficient, stiffness_coefficient, single);
    Vector vectorised, portable;
    set_block_product_vectorised(true);
    blocks.multiply(x, vectorised, serial_executor());
    set_block_product_vectorised(false);
    blocks.multiply(x, portable, serial_executor());
    set_block_product_vectorised(true);
    EXPECT_TRUE(same_bits(vectorised, portable)) << (single ? "float" : "double");
    if (!single) {
      EXPECT_TRUE(same_bits(portable, eigen_blocks));
    }
  }
  std::printf("block product: %s kernel\n", block_product_vectorised() ? "AVX2" : "portable");
}

// The float copy is the system with every entry rounded to float, multiplied in double.
TEST(BlockSystem, TheFloatCopyIsTheRoundedSystem) {
  const auto model = small_efg();
  const BlockMatrix k = model->rest_stiffness_job()();
  std::vector<std::uint8_t> fixed(static_cast<size_t>(model->node_count()), 0);
  for (int i = 0; i < model->node_count(); i += 5) fixed[static_cast<size_t>(i)] = 1;
  const double mass_coefficient = 1.02, stiffness_coefficient = 1e-4;
  const BlockSystem single(k, model->lumped_masses(), fixed, mass_coefficient, stiffness_coefficient, true);
  Eigen::SparseMatrix<double> rounded = k.system(model->lumped_masses(), fixed, mass_coefficient, stiffness_coefficient);
  for (Eigen::Index i = 0; i < rounded.nonZeros(); ++i)
    rounded.valuePtr()[i] = static_cast<double>(static_cast<float>(rounded.valuePtr()[i]));
  const Vector x = random_vector(3 * model->node_count(), 10);
  Vector y;
  single.multiply(x, y, serial_executor());
  const Vector reference = rounded * x;
  EXPECT_LE((y - reference).cwiseAbs().maxCoeff(), 1e-12 * reference.cwiseAbs().maxCoeff());
  EXPECT_EQ(single.diagonal(), Vector(rounded.diagonal()));
  EXPECT_TRUE(single.single());
}

// A double system rounded afterwards (the rest factor's, after its eigenvalue estimate) is the
// one built in float.
TEST(BlockSystem, RoundingADoubleSystemIsBuildingItInFloat) {
  const auto model = small_efg();
  const BlockMatrix k = model->rest_stiffness_job()();
  std::vector<std::uint8_t> fixed(static_cast<size_t>(model->node_count()), 0);
  for (int i = 0; i < model->node_count(); i += 5) fixed[static_cast<size_t>(i)] = 1;
  const BlockSystem single(k, model->lumped_masses(), fixed, 1.02, 1e-4, true);
  BlockSystem rounded(k, model->lumped_masses(), fixed, 1.02, 1e-4);
  EXPECT_FALSE(rounded.single());
  rounded.round_to_single();
  EXPECT_TRUE(rounded.single());
  const Vector x = random_vector(3 * model->node_count(), 11);
  Vector a, b;
  single.multiply(x, a, serial_executor());
  rounded.multiply(x, b, serial_executor());
  EXPECT_EQ(a, b);
  EXPECT_EQ(single.diagonal(), rounded.diagonal());
}

TEST(WarpedPreconditioner, EfgSolvesARigidlyTurnedBodyInOneIteration) { expect_exact_for_rigid_rotation(*small_efg()); }

TEST(WarpedPreconditioner, TetSolvesARigidlyTurnedBodyInOneIteration) { expect_exact_for_rigid_rotation(*small_fem()); }

// An executor that defers its async jobs until told, so the test controls when a build ends.
class DeferredExecutor final : public Executor {
 public:
  int thread_count() const override { return 1; }
  void parallel_for(int count, const std::function<void(int, int)>& task, int) override { task(0, count); }
  void run_beside(const std::function<void()>& own, const std::function<void()>& side) override {
    own();
    side();
  }
  std::shared_future<void> run_async(std::function<void()> job) override {
    started++;
    return std::async(std::launch::deferred, std::move(job)).share();
  }
  int started = 0;
};

// A small tet body, nothing fixed, and a rest preconditioner of latency 3 whose builds run
// when the step asks for them (DeferredExecutor).
struct LatencyRig {
  std::unique_ptr<CorotationalTetFem> model = small_fem();
  std::vector<std::uint8_t> fixed = std::vector<std::uint8_t>(static_cast<size_t>(model->node_count()), 0);
  PreconditionerSettings settings;
  RestPreconditioner preconditioner;
  DeferredExecutor executor;
  LatencyRig() {
    model->update_rotations(model->rest_positions());
    settings.latency = 3;
  }
};

TEST(RestPreconditioner, ANewFactorTakesOverExactlyLatencyStepsAfterTheChange) {
  LatencyRig rig;
  auto& [model, fixed, settings, preconditioner, executor] = rig;
  std::uint64_t revision = 0;
  PreconditionerReport report;
  const RestFactor* first = preconditioner.prepare(settings, *model, fixed, 1, 1e-4, revision, 0, executor, report);
  ASSERT_NE(first, nullptr);
  EXPECT_TRUE(report.built_here);
  EXPECT_EQ(executor.started, 0);  // the first is built on the step's thread
  revision = 1;                    // a cut at step 5
  for (long long step = 1; step < 5; ++step) {
    report = {};
    EXPECT_EQ(preconditioner.prepare(settings, *model, fixed, 1, 1e-4, revision - 1, step, executor, report), first);
    EXPECT_EQ(report.age, 0);
  }
  for (long long step = 5; step < 8; ++step) {
    report = {};
    EXPECT_EQ(preconditioner.prepare(settings, *model, fixed, 1, 1e-4, revision, step, executor, report), first);
    EXPECT_EQ(report.age, step - 5);
    EXPECT_FALSE(report.adopted);
  }
  EXPECT_EQ(executor.started, 1);
  report = {};
  const RestFactor* second = preconditioner.prepare(settings, *model, fixed, 1, 1e-4, revision, 8, executor, report);
  EXPECT_NE(second, first);
  EXPECT_TRUE(report.adopted);
  EXPECT_EQ(report.age, 0);
  EXPECT_EQ(preconditioner.builds(), 2);
}

// A build beside the steps that fails (here its system has no mass term, which RestFactor
// refuses) leaves the factor in use in place and says why; the same topology is not built
// again, and the next change's build takes over as usual.
TEST(RestPreconditioner, AFailedBuildLeavesTheFactorInUse) {
  LatencyRig rig;
  auto& [model, fixed, settings, preconditioner, executor] = rig;
  PreconditionerReport report;
  const RestFactor* first = preconditioner.prepare(settings, *model, fixed, 1, 1e-4, 0, 0, executor, report);
  ASSERT_NE(first, nullptr);
  for (long long step = 1; step < 4; ++step) {  // a cut at step 1: its build is due at 4
    report = {};
    EXPECT_EQ(preconditioner.prepare(settings, *model, fixed, 0, 1e-4, 1, step, executor, report), first);
  }
  report = {};
  EXPECT_EQ(preconditioner.prepare(settings, *model, fixed, 0, 1e-4, 1, 4, executor, report), first);
  EXPECT_FALSE(report.adopted);
  EXPECT_NE(report.build_error.find("mass coefficient"), std::string::npos) << report.build_error;
  for (long long step = 5; step < 12; ++step) {
    report = {};
    EXPECT_EQ(preconditioner.prepare(settings, *model, fixed, 1, 1e-4, 1, step, executor, report), first);
    EXPECT_TRUE(report.build_error.empty());
  }
  EXPECT_EQ(executor.started, 1);  // revision 1 is not built again
  for (long long step = 12; step < 15; ++step) {
    report = {};
    EXPECT_EQ(preconditioner.prepare(settings, *model, fixed, 1, 1e-4, 2, step, executor, report), first);
  }
  report = {};
  const RestFactor* second = preconditioner.prepare(settings, *model, fixed, 1, 1e-4, 2, 15, executor, report);
  EXPECT_NE(second, first);
  EXPECT_TRUE(report.adopted);
  EXPECT_EQ(report.age, 0);
  EXPECT_EQ(executor.started, 2);
}

TEST(RestPreconditioner, JacobiAndModelsWithoutRestStiffnessGetNoFactor) {
  auto model = small_fem();
  PreconditionerSettings jacobi;
  jacobi.kind = PreconditionerKind::jacobi;
  RestPreconditioner preconditioner;
  PreconditionerReport report;
  EXPECT_EQ(preconditioner.prepare(jacobi, *model, {}, 1, 1e-4, 0, 0, serial_executor(), report), nullptr);
  EXPECT_EQ(preconditioner.builds(), 0);
}

}  // namespace
}  // namespace incise::physics

namespace incise::physics {
namespace {

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
