// The assembled current system (solver.preconditioner "multigrid_current"): the EFG model's
// corotated K(x) in blocks against its own matrix-free product on a bent, turned body and after
// a cut, the node rotations that warp its coarse correction, its products (double, several in
// one pass, the paired float copy and its halves) bit for bit against their references, and its
// bits independent of the threads. The V-cycle on it: test_current_vcycle.cpp.
#include "physics/efg/corotational_efg.hpp"
#include "physics/solve/block_product.hpp"
#include "physics/solve/current_system.hpp"
#include "physics/solve/half_float.hpp"
#include "physics/solve/paired_blocks.hpp"
#include "physics/solve/element_assembly.hpp"
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
#include <limits>
#include <memory>
#include <random>
#include <thread>

namespace incise::physics {
namespace {

using fixtures::BentBall;
using fixtures::random_vector;
using fixtures::same_bits;
using test::ShufflingExecutor;
using test::TwoThreadExecutor;

// A's product as implicit_euler_step computes it matrix-free, with one spring.
Vector matrix_free_system(const CorotationalEfg& model, const NodalSpring& spring, double mass_coefficient,
                          double stiffness_coefficient, const Vector& p) {
  Vector stiffness = Vector::Zero(p.size());
  model.add_stiffness_product(p, stiffness);
  stiffness.segment<3>(3 * spring.node) += spring.stiffness * p.segment<3>(3 * spring.node);
  Vector out(p.size());
  for (int i = 0; i < model.node_count(); ++i)
    out.segment<3>(3 * i) = mass_coefficient * model.lumped_masses()[i] * p.segment<3>(3 * i);
  return out + stiffness_coefficient * stiffness;
}

void expect_assembled_equals_matrix_free(const CorotationalEfg& model, const std::vector<std::uint8_t>& fixed) {
  const BlockMatrix& k = *model.current_stiffness();
  NodalSpring spring;
  spring.node = 3;
  spring.stiffness = Mat3::Identity() * 40.0 + Vec3(1, 2, 3) * Vec3(1, 2, 3).transpose();
  const double mass_coefficient = 1.02, stiffness_coefficient = 1e-4;
  const CurrentSystem system(k, model.lumped_masses(), fixed, std::span<const NodalSpring>(&spring, 1), mass_coefficient,
                             stiffness_coefficient);
  // CG's vectors are zero on the fixed nodes; its residual there is never read.
  Vector p = random_vector(3 * model.node_count(), 11);
  for (int i = 0; i < model.node_count(); ++i)
    if (fixed[static_cast<size_t>(i)]) p.segment<3>(3 * i).setZero();
  Vector assembled;
  system.multiply(p, assembled, serial_executor());
  Vector reference = matrix_free_system(model, spring, mass_coefficient, stiffness_coefficient, p);
  Vector diagonal_reference = Vector::Zero(p.size());
  model.add_stiffness_diagonal(diagonal_reference);
  diagonal_reference.segment<3>(3 * spring.node) += spring.stiffness.diagonal();
  Vector diagonal = system.diagonal();
  for (int i = 0; i < model.node_count(); ++i) {
    diagonal_reference.segment<3>(3 * i) = Vec3::Constant(mass_coefficient * model.lumped_masses()[i]) +
                                           stiffness_coefficient * diagonal_reference.segment<3>(3 * i);
    if (fixed[static_cast<size_t>(i)]) {
      EXPECT_EQ(Vec3(assembled.segment<3>(3 * i)), Vec3::Zero());  // the identity's row of a zero entry
      reference.segment<3>(3 * i).setZero();
      diagonal.segment<3>(3 * i).setZero();
      diagonal_reference.segment<3>(3 * i).setZero();
    }
  }
  EXPECT_LE((assembled - reference).cwiseAbs().maxCoeff(), 1e-12 * reference.cwiseAbs().maxCoeff());
  EXPECT_LE((diagonal - diagonal_reference).cwiseAbs().maxCoeff(), 1e-12 * diagonal_reference.cwiseAbs().maxCoeff());
  // K alone, nothing fixed: every row against add_stiffness_product.
  const std::vector<std::uint8_t> none;
  const CurrentSystem bare(k, model.lumped_masses(), none, {}, 0.0, 1.0);
  const Vector q = random_vector(3 * model.node_count(), 5);
  Vector kq, kq_reference = Vector::Zero(q.size());
  bare.multiply(q, kq, serial_executor());
  model.add_stiffness_product(q, kq_reference);
  EXPECT_LE((kq - kq_reference).cwiseAbs().maxCoeff(), 1e-12 * kq_reference.cwiseAbs().maxCoeff());
}

TEST(CurrentSystem, EqualsTheMatrixFreeProductOnABentTurnedBodyAndAfterACut) {
  BentBall ball;
  CorotationalEfg& model = *ball.model;
  model.update_rotations(ball.x);
  expect_assembled_equals_matrix_free(model, ball.fixed);
  // A cut's edits: a reversed row (the pattern's order moves), a row with a neighbour less,
  // an element taken out; the plan is rebuilt for the new rows.
  const int elements = model.element_count();
  for (int e : {5, elements / 2}) {
    const size_t base = static_cast<size_t>(e) * model.row_stride();
    std::vector<int> row(model.neighbours().begin() + base, model.neighbours().begin() + base + model.row_lengths()[e]);
    std::reverse(row.begin(), row.end());
    if (e != 5 && row.size() > 6) row.pop_back();
    model.set_neighbourhood(e, row);
  }
  model.deactivate_element(elements / 3);
  model.update_rotations(ball.x);
  expect_assembled_equals_matrix_free(model, ball.fixed);
}

// The node rotations (each node's mean of its elements' rotations, the warp of the coarse
// correction) summed per node on the executor's threads have the bits of NodeRotations' one
// serial pass, also after cut edits: a model whose incidence was laid before the edits (and is
// laid again after them) and one that lays it only after them give the same rotations, on
// one thread and on shuffled ranges.
TEST(CurrentSystem, TheNodeRotationsFollowTheCutsWithTheBitsOfTheSerialMean) {
  BentBall before, after;
  ShufflingExecutor shuffling;
  before.model->update_rotations(before.x);
  after.model->update_rotations(after.x);  // the same history: the rotations' warm starts alike
  std::vector<Eigen::Quaterniond> first, edited, fresh, serial;
  before.model->node_rotations(first);  // lays the incidence before the edits
  for (BentBall* ball : {&before, &after}) {
    CorotationalEfg& model = *ball->model;
    const int elements = model.element_count();
    for (int e : {5, elements / 2}) {
      const size_t base = static_cast<size_t>(e) * model.row_stride();
      std::vector<int> row(model.neighbours().begin() + base, model.neighbours().begin() + base + model.row_lengths()[e]);
      std::reverse(row.begin(), row.end());
      if (row.size() > 6) row.pop_back();
      model.set_neighbourhood(e, row);
    }
    model.deactivate_element(elements / 3);
    model.update_rotations(ball->x);
  }
  before.model->node_rotations(edited);
  after.model->set_executor(&shuffling);
  after.model->node_rotations(fresh);
  ASSERT_EQ(edited.size(), fresh.size());
  // Against NodeRotations' serial pass over the elements, from the element rotations as
  // matrices (their quaternions round differently from the model's kept ones).
  const CorotationalEfg& model = *after.model;
  NodeRotations mean;
  mean.reset(model.node_count());
  for (int e = 0; e < model.element_count(); ++e) {
    if (!(model.element_volumes()[static_cast<size_t>(e)] > 0)) continue;
    const size_t base = static_cast<size_t>(e) * model.row_stride();
    for (int k = 0; k < model.row_lengths()[static_cast<size_t>(e)]; ++k)
      mean.add(model.neighbours()[base + k], Eigen::Quaterniond(model.rotations()[static_cast<size_t>(e)]),
               model.element_volumes()[static_cast<size_t>(e)]);
  }
  mean.finish(serial);
  bool moved = false;
  for (size_t node = 0; node < fresh.size(); ++node) {
    EXPECT_EQ(edited[node].coeffs(), fresh[node].coeffs()) << "node " << node;
    EXPECT_LE(fresh[node].angularDistance(serial[node]), 1e-12) << "node " << node;
    moved = moved || edited[node].coeffs() != first[node].coeffs();
  }
  EXPECT_TRUE(moved);  // the edits changed some node's mean
}

// The product as CurrentSystem wrote it in Eigen before its kernel (current_product.hpp): each
// free row summed over its free columns in column order, then its springs, then the mass.
Vector eigen_product(const BlockMatrix& k, const Vector& masses, const std::vector<std::uint8_t>& fixed,
                     std::span<const NodalSpring> springs, double mass_coefficient, double stiffness_coefficient,
                     const Vector& x) {
  std::vector<Mat3> spring_blocks(static_cast<size_t>(k.nodes()), Mat3::Zero());
  for (const NodalSpring& spring : springs) spring_blocks[static_cast<size_t>(spring.node)] += spring.stiffness;
  Vector y(x.size());
  for (int row = 0; row < k.nodes(); ++row) {
    const Eigen::Index offset = 3 * static_cast<Eigen::Index>(row);
    if (fixed[static_cast<size_t>(row)]) {
      y.segment<3>(offset) = x.segment<3>(offset);
      continue;
    }
    Vec3 sum = Vec3::Zero();
    for (int i = k.row_start()[static_cast<size_t>(row)]; i < k.row_start()[static_cast<size_t>(row) + 1]; ++i) {
      const int column = k.columns()[static_cast<size_t>(i)];
      if (fixed[static_cast<size_t>(column)]) continue;
      sum.noalias() += k.blocks()[static_cast<size_t>(i)] * x.segment<3>(3 * static_cast<Eigen::Index>(column));
    }
    if (!springs.empty()) sum.noalias() += spring_blocks[static_cast<size_t>(row)] * x.segment<3>(offset);
    y.segment<3>(offset) = mass_coefficient * masses[row] * x.segment<3>(offset) + stiffness_coefficient * sum;
  }
  return y;
}

// K with every block entry rounded to float and widened back, a diagonal block's lower
// triangle its upper one's: the matrix CurrentVcycle's single-precision smoother multiplies by.
BlockMatrix rounded_to_float(const BlockMatrix& k) {
  std::vector<Mat3> blocks = k.blocks();
  for (Mat3& block : blocks) block = block.cast<float>().cast<double>();
  for (int row = 0; row < k.nodes(); ++row)
    for (int i = k.row_start()[static_cast<size_t>(row)]; i < k.row_start()[static_cast<size_t>(row) + 1]; ++i)
      if (k.columns()[static_cast<size_t>(i)] == row)
        blocks[static_cast<size_t>(i)] = blocks[static_cast<size_t>(i)].triangularView<Eigen::Upper>().toDenseMatrix().selfadjointView<Eigen::Upper>();
  return BlockMatrix(k.nodes(), k.row_start(), k.columns(), std::move(blocks));
}

// Whether every block (r, c) is block (c, r) transposed, bit for bit; `diagonal`: counts the
// diagonal blocks' own symmetry too.
int asymmetric_blocks(const BlockMatrix& k, const std::vector<Mat3>& blocks, bool diagonal) {
  int differing = 0;
  for (int row = 0; row < k.nodes(); ++row)
    for (int i = k.row_start()[static_cast<size_t>(row)]; i < k.row_start()[static_cast<size_t>(row) + 1]; ++i) {
      const int column = k.columns()[static_cast<size_t>(i)];
      if (column == row && !diagonal) continue;
      const auto first = k.columns().begin() + k.row_start()[static_cast<size_t>(column)];
      const auto mirror = std::lower_bound(first, k.columns().begin() + k.row_start()[static_cast<size_t>(column) + 1], row);
      if (mirror == k.columns().end() || *mirror != row) return -1;
      const Mat3 transposed = blocks[static_cast<size_t>(mirror - k.columns().begin())].transpose();
      differing += std::memcmp(transposed.data(), blocks[static_cast<size_t>(i)].data(), sizeof(Mat3)) != 0;
    }
  return differing;
}

// The kernel's product, AVX2 or portable, on any split of the rows, has the Eigen product's
// bits: with springs (one on a fixed node, two on one node), and with x zero or not (even NaN)
// on the fixed nodes.
TEST(CurrentSystem, TheProductHasTheBitsOfTheEigenProduct) {
  BentBall ball;
  CorotationalEfg& model = *ball.model;
  model.update_rotations(ball.x);
  const BlockMatrix& k = *model.current_stiffness();
  int fixed_node = 0;
  while (!ball.fixed[static_cast<size_t>(fixed_node)]) ++fixed_node;
  std::vector<NodalSpring> springs(3);
  springs[0].node = springs[1].node = 3;
  springs[2].node = fixed_node;
  springs[0].stiffness = Mat3::Identity() * 40.0 + Vec3(1, 2, 3) * Vec3(1, 2, 3).transpose();
  springs[1].stiffness = Mat3::Identity() * 7.0 + Vec3(3, -1, 2) * Vec3(3, -1, 2).transpose();
  springs[2].stiffness = Mat3::Identity() * 11.0;
  const double mass_coefficient = 1.02, stiffness_coefficient = 1e-4;
  const CurrentSystem system(k, model.lumped_masses(), ball.fixed, springs, mass_coefficient, stiffness_coefficient);
  const CurrentSystem bare(k, model.lumped_masses(), ball.fixed, {}, mass_coefficient, stiffness_coefficient);
  Vector on_fixed = random_vector(ball.x.size(), 21), zero_on_fixed = on_fixed;
  for (int i = 0; i < model.node_count(); ++i)
    if (ball.fixed[static_cast<size_t>(i)]) zero_on_fixed.segment<3>(3 * i).setZero();
  on_fixed[3 * fixed_node + 1] = std::numeric_limits<double>::quiet_NaN();
  ShufflingExecutor shuffling;
  for (const bool vectorised : {false, true}) {
    set_block_product_vectorised(vectorised);
    for (const Vector* x : {&zero_on_fixed, &on_fixed}) {
      for (const bool with_springs : {true, false}) {
        const std::span<const NodalSpring> used =
            with_springs ? std::span<const NodalSpring>(springs) : std::span<const NodalSpring>();
        const Vector reference =
            eigen_product(k, model.lumped_masses(), ball.fixed, used, mass_coefficient, stiffness_coefficient, *x);
        Vector serial, split;
        (with_springs ? system : bare).multiply(*x, serial, serial_executor());
        (with_springs ? system : bare).multiply(*x, split, shuffling);
        // NaN only where x has it (a fixed row's identity), compared as bits.
        ASSERT_EQ(serial.size(), reference.size());
        EXPECT_EQ(0, std::memcmp(serial.data(), reference.data(), sizeof(double) * static_cast<size_t>(serial.size())))
            << "vectorised " << vectorised << ", springs " << with_springs;
        EXPECT_EQ(0, std::memcmp(split.data(), reference.data(), sizeof(double) * static_cast<size_t>(split.size())));
      }
    }
  }
  set_block_product_vectorised(true);
}

// Several products in one pass over K (CG's start, multiply_several) have each the bits of
// multiply()'s, whatever the threads, vectors with nonzero or NaN fixed entries among them.
TEST(CurrentSystem, SeveralProductsInOnePassHaveTheBitsOfOneEach) {
  BentBall ball;
  CorotationalEfg& model = *ball.model;
  model.update_rotations(ball.x);
  const NodalSpring spring{5, Vec3::Zero(), Mat3::Identity() * 30.0 + Mat3::Constant(2.0)};
  const CurrentSystem system(*model.current_stiffness(), model.lumped_masses(), ball.fixed,
                             std::span<const NodalSpring>(&spring, 1), 1.02, 1e-4);
  int fixed_node = 0;
  while (!ball.fixed[static_cast<size_t>(fixed_node)]) ++fixed_node;
  std::vector<Vector> x;
  for (unsigned seed = 31; seed < 36; ++seed) x.push_back(random_vector(ball.x.size(), seed));
  x[1][3 * fixed_node] = 2.5;
  x[3][3 * fixed_node + 2] = std::numeric_limits<double>::quiet_NaN();
  ShufflingExecutor shuffling;
  TwoThreadExecutor two;
  for (Executor* executor : std::array<Executor*, 3>{&serial_executor(), &shuffling, &two}) {
    std::vector<Vector> several(x.size());
    system.multiply_several(x, several, *executor);
    for (size_t k = 0; k < x.size(); ++k) {
      Vector one;
      system.multiply(x[k], one, serial_executor());
      ASSERT_EQ(several[k].size(), one.size());
      EXPECT_EQ(0, std::memcmp(several[k].data(), one.data(), sizeof(double) * static_cast<size_t>(one.size()))) << "vector " << k;
    }
  }
}

// The V-cycle's float product on K's paired copy (paired_blocks.hpp): the AVX2 + FMA kernel and
// the portable one give the same bits, however the rows are split; against the double product
// on K's blocks and x rounded to float (the same inputs, summed in double) it differs only by
// the float sums' rounding. With springs and fixed rows (y = x there, bit for bit).
TEST(CurrentSystem, ThePairedFloatProductIsTheRoundedProductSummedInFloat) {
  BentBall ball;
  CorotationalEfg& model = *ball.model;
  model.update_rotations(ball.x);
  const BlockMatrix& k = *model.current_stiffness();
  std::vector<NodalSpring> springs(2);
  springs[0].node = springs[1].node = 3;
  springs[0].stiffness = Mat3::Identity() * 40.0 + Vec3(1, 2, 3) * Vec3(1, 2, 3).transpose();
  springs[1].stiffness = Mat3::Identity() * 7.0 + Vec3(3, -1, 2) * Vec3(3, -1, 2).transpose();
  const double mass_coefficient = 1.02, stiffness_coefficient = 1e-4;
  const CurrentSystem system(k, model.lumped_masses(), ball.fixed, springs, mass_coefficient, stiffness_coefficient);
  ShufflingExecutor shuffling;
  const PairedBlocks paired(system.rows(), k.nodes(), shuffling);
  ASSERT_EQ(paired.operand_size(), 4 * static_cast<size_t>(k.nodes() + 1));
  const Vector x = random_vector(ball.x.size(), 31);  // nonzero on the fixed nodes: the operand zeroes them
  std::vector<float> operand(paired.operand_size(), 0.0f);
  PairedBlocks::round_operand(system.rows(), x.data(), operand.data(), 0, k.nodes());
  Vector rounded_x = x;
  for (int i = 0; i < k.nodes(); ++i)
    for (int a = 0; a < 3; ++a) {
      const float expected = ball.fixed[static_cast<size_t>(i)] ? 0.0f : static_cast<float>(x[3 * i + a]);
      ASSERT_EQ(operand[4 * static_cast<size_t>(i) + static_cast<size_t>(a)], expected);
      rounded_x[3 * i + a] = expected;
    }
  // The reference: A's double product with K's blocks rounded and x rounded, free rows; x itself
  // on the fixed ones.
  Vector reference = eigen_product(rounded_to_float(k), model.lumped_masses(), ball.fixed, springs, mass_coefficient,
                                   stiffness_coefficient, rounded_x);
  for (int i = 0; i < k.nodes(); ++i) {
    const Vec3 mass_term = mass_coefficient * model.lumped_masses()[i] * (x.segment<3>(3 * i) - rounded_x.segment<3>(3 * i));
    reference.segment<3>(3 * i) = ball.fixed[static_cast<size_t>(i)] ? Vec3(x.segment<3>(3 * i))
                                                                      : Vec3(reference.segment<3>(3 * i) + mass_term);
  }
  Vector portable;
  for (const bool vectorised : {false, true}) {
    set_block_product_vectorised(vectorised);
    Vector whole(x.size()), split(x.size());
    paired.multiply_rows(system.rows(), x.data(), operand.data(), whole.data(), 0, k.nodes());
    for (int begin = 0; begin < k.nodes(); begin += 37)
      paired.multiply_rows(system.rows(), x.data(), operand.data(), split.data(), begin, std::min(k.nodes(), begin + 37));
    EXPECT_TRUE(same_bits(whole, split)) << "vectorised " << vectorised;
    for (int i = 0; i < k.nodes(); ++i) {
      if (ball.fixed[static_cast<size_t>(i)]) {
        EXPECT_TRUE(same_bits(whole.segment<3>(3 * i), x.segment<3>(3 * i))) << "fixed row " << i;
      }
    }
    // Float sums: within a float rounding or so of the largest entry of the product.
    const double scale = reference.cwiseAbs().maxCoeff();
    EXPECT_LE((whole - reference).cwiseAbs().maxCoeff(), 1e-6 * scale) << "vectorised " << vectorised;
    EXPECT_GT((whole - reference).cwiseAbs().maxCoeff(), 0.0);  // the float sums show
    if (vectorised) {
      EXPECT_TRUE(same_bits(whole, portable)) << "AVX2 + FMA against portable";
    } else {
      portable = whole;
    }
  }
  set_block_product_vectorised(true);
}

// The paired copy's halves (the smoother's entries for a large K): each the nearest half of the
// float entry scaled by 2^-s, symmetric bit for bit; their product's AVX2 + F16C kernel and the
// portable one give the same bits, within half precision of the float product. A copy rebuilt
// into a larger one's storage (PairedBlocks::build) has the bits of a fresh one.
TEST(CurrentSystem, ThePairedCopysHalvesRoundItsFloatsAndMultiplyAlike) {
  BentBall ball;
  CorotationalEfg& model = *ball.model;
  model.update_rotations(ball.x);
  const BlockMatrix& k = *model.current_stiffness();
  const CurrentSystem system(k, model.lumped_masses(), ball.fixed, {}, 0.0, 1.0);  // A = K on the free rows
  const PairedBlocks paired(system.rows(), k.nodes(), serial_executor(), true);
  ASSERT_TRUE(paired.has_half());
  const double scale = paired.half_scale();
  EXPECT_EQ(scale, std::ldexp(1.0, std::ilogb(scale)));  // a power of two
  std::vector<Mat3> halves(static_cast<size_t>(k.block_count()));
  for (int row = 0; row < k.nodes(); ++row)
    for (int b = k.row_start()[static_cast<size_t>(row)]; b < k.row_start()[static_cast<size_t>(row) + 1]; ++b) {
      const int index = b - k.row_start()[static_cast<size_t>(row)];
      const Mat3 single = paired.block(row, index), half = paired.block(row, index, PairedPrecision::half);
      halves[static_cast<size_t>(b)] = half;
      for (int i = 0; i < 9; ++i) {
        const float scaled = static_cast<float>(single.data()[i] / scale);
        ASSERT_EQ(half.data()[i], scale * static_cast<double>(half_to_float(float_to_half(scaled)))) << "row " << row;
        ASSERT_LT(std::abs(scaled), 32768.0f);  // the scale keeps every entry a normal-range half
      }
    }
  EXPECT_EQ(asymmetric_blocks(k, halves, true), 0);

  const Vector x = random_vector(ball.x.size(), 8);
  std::vector<float> operand(paired.operand_size(), 0.0f);
  PairedBlocks::round_operand(system.rows(), x.data(), operand.data(), 0, k.nodes());
  Vector single(x.size()), portable(x.size()), vectorised(x.size());
  paired.multiply_rows(system.rows(), x.data(), operand.data(), single.data(), 0, k.nodes());
  set_block_product_vectorised(false);
  paired.multiply_rows(system.rows(), x.data(), operand.data(), portable.data(), 0, k.nodes(), PairedPrecision::half);
  set_block_product_vectorised(true);
  paired.multiply_rows(system.rows(), x.data(), operand.data(), vectorised.data(), 0, k.nodes(), PairedPrecision::half);
  EXPECT_TRUE(same_bits(portable, vectorised));
  // Entries within 2^-11 of themselves (and of the scale's 2^-25 where tiny): the products
  // within a few thousandths of K x's largest entry.
  const double difference = (vectorised - single).cwiseAbs().maxCoeff() / single.cwiseAbs().maxCoeff();
  std::printf("half against single product: %.3g of its largest entry\n", difference);
  EXPECT_GT(difference, 0.0);
  EXPECT_LT(difference, 5e-3);

  // Rebuilt into a larger copy's storage.
  PairedBlocks reused(system.rows(), k.nodes(), serial_executor(), true);
  BentBall other;
  other.model->update_rotations(other.x);
  const std::vector<std::uint8_t> none;
  const CurrentSystem unfixed(*other.model->current_stiffness(), other.model->lumped_masses(), none, {}, 1.0, 1e-4);
  reused.build(unfixed.rows(), unfixed.nodes(), serial_executor(), true);
  reused.build(system.rows(), k.nodes(), serial_executor(), false);
  EXPECT_FALSE(reused.has_half());
  Vector again(x.size());
  reused.multiply_rows(system.rows(), x.data(), operand.data(), again.data(), 0, k.nodes());
  EXPECT_TRUE(same_bits(again, single));
}

// The refill writes each lower block as its mirror's transpose, but sums a diagonal block's
// entries (i, j) and (j, i) in different orders: K is symmetric bit for bit off the diagonal
// blocks, to round-off on them. The paired copy takes their upper entries: symmetric bit for
// bit.
TEST(CurrentSystem, ThePairedCopyOfTheCurrentStiffnessIsSymmetricBitForBit) {
  BentBall ball;
  ball.model->update_rotations(ball.x);
  const BlockMatrix& k = *ball.model->current_stiffness();
  const CurrentSystem system(k, ball.model->lumped_masses(), ball.fixed, {}, 1.0, 1e-4);
  const PairedBlocks paired(system.rows(), k.nodes(), serial_executor());
  EXPECT_EQ(asymmetric_blocks(k, k.blocks(), false), 0);
  const int diagonal_asymmetric = asymmetric_blocks(k, k.blocks(), true);
  std::printf("K's diagonal blocks not symmetric bit for bit: %d of %d\n", diagonal_asymmetric, k.nodes());
  std::vector<Mat3> widened(static_cast<size_t>(k.block_count()));
  for (int row = 0; row < k.nodes(); ++row)
    for (int b = k.row_start()[static_cast<size_t>(row)]; b < k.row_start()[static_cast<size_t>(row) + 1]; ++b) {
      widened[static_cast<size_t>(b)] = paired.block(row, b - k.row_start()[static_cast<size_t>(row)]);
      const Mat3 rounded = k.blocks()[static_cast<size_t>(b)].cast<float>().cast<double>();
      // Off the diagonal the rounded block itself; on it, its upper entries mirrored.
      for (int i = 0; i < 3; ++i)
        for (int j = 0; j < 3; ++j) {
          const bool mirrored = k.columns()[static_cast<size_t>(b)] == row && i > j;
          ASSERT_EQ(widened[static_cast<size_t>(b)](i, j), mirrored ? rounded(j, i) : rounded(i, j)) << "row " << row;
        }
    }
  EXPECT_EQ(asymmetric_blocks(k, widened, true), 0);
}

TEST(CurrentSystem, TheAssemblyHasTheSameBitsHoweverTheRowsAreSplit) {
  BentBall ball;
  ball.model->update_rotations(ball.x);
  const std::vector<Mat3> serial = ball.model->current_stiffness()->blocks();
  ShufflingExecutor shuffling;
  ball.model->set_executor(&shuffling);
  const std::vector<Mat3>& shuffled = ball.model->current_stiffness()->blocks();
  ASSERT_EQ(serial.size(), shuffled.size());
  EXPECT_EQ(0, std::memcmp(serial.data(), shuffled.data(), sizeof(Mat3) * serial.size()));
  ball.model->set_executor(nullptr);
  // The particle cells' vectorised sums (element_assembly.cpp) against the portable loop.
  set_element_assembly_vectorised(false);
  const std::vector<Mat3>& portable = ball.model->current_stiffness()->blocks();
  set_element_assembly_vectorised(true);
  EXPECT_EQ(0, std::memcmp(serial.data(), portable.data(), sizeof(Mat3) * serial.size()));
}

}  // namespace
}  // namespace incise::physics
