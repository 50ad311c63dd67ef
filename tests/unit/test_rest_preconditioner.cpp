// The rest-shape preconditioner (physics/solve/): the assembled K0 against the models' own
// matrix-free products, its block system and kernels, the warp exact for a rigid rotation, and
// which factor a step uses. The coarse space is tested in test_coarse_space.cpp, the rest
// V-cycle in test_multigrid.cpp.
#include "physics/core/cg.hpp"
#include "physics/core/implicit_euler.hpp"
#include "physics/efg/corotational_efg.hpp"
#include "physics/fem/corotational_fem.hpp"
#include "physics/fem/tet_mesh.hpp"
#include "physics/solve/block_product.hpp"
#include "physics/solve/block_system.hpp"
#include "physics/solve/rest_preconditioner.hpp"
#include "physics/solve/warped_preconditioner.hpp"

#include "tests/unit/bent_ball.hpp"
#include "tests/unit/test_executors.hpp"

#include <gtest/gtest.h>

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
using fixtures::same_bits;
using fixtures::small_efg;
using fixtures::tissue;
using test::ShufflingExecutor;

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
