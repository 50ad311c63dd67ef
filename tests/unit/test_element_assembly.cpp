// The grouped assembly of Gram-type element blocks (physics/solve/element_assembly.hpp): elements
// that share a node set in different orders, a repeated node, an element of weight zero, against
// a sum of every element's own blocks; the pattern kept or rebuilt through edits; the bits the
// same however the rows are split and whatever edits led to the rows; the 8-node groups' AVX2
// sums the bits of the portable loop, beside irregular groups (cut cells); rows edited a few at a
// time (a cut's re-selection) regrouped and re-planned to what grouping and planning them afresh
// gives.
#include "physics/core/model.hpp"
#include "physics/solve/element_assembly.hpp"
#include "physics/solve/element_groups.hpp"

#include "tests/unit/test_executors.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <cstdio>
#include <cstring>
#include <map>
#include <random>
#include <utility>

namespace incise::physics {
namespace {

// Pieces of 3: the small test matrices still split into several.
using Shuffling = test::ShufflingExecutor;

constexpr double lambda = 3.0, mu = 0.7;

// C(S) = lambda S + mu S^T + mu tr(S) I, the corotated EFG's block.
void combine(const Mat3& s, Mat3& out) {
  out += lambda * s + mu * s.transpose();
  out.diagonal().array() += mu * s.trace();
}

struct Elements {
  int nodes = 12, stride = 5;
  std::vector<int> lengths, neighbours;
  std::vector<std::vector<Vec3>> vectors;  // per element, per entry k
  std::vector<double> weights;

  void add(std::vector<int> row, std::mt19937& random) {
    std::uniform_real_distribution<double> uniform(-1, 1);
    lengths.push_back(static_cast<int>(row.size()));
    row.resize(static_cast<size_t>(stride), 0);
    neighbours.insert(neighbours.end(), row.begin(), row.end());
    vectors.emplace_back();
    for (int k = 0; k < lengths.back(); ++k) vectors.back().emplace_back(uniform(random), uniform(random), uniform(random));
    weights.push_back(1.0 + uniform(random));
  }
};

Elements sample_elements() {
  std::mt19937 random(3);
  Elements elements;
  elements.add({0, 1, 2, 3}, random);
  elements.add({4, 5, 6, 7, 8}, random);
  elements.add({3, 1, 0, 2}, random);  // the first's nodes, in another order
  elements.add({2, 9, 10, 11}, random);
  elements.add({1, 2, 3, 0}, random);
  elements.add({5, 5, 6, 7}, random);  // a repeated node
  elements.add({8, 7, 6, 5, 4}, random);
  elements.weights[4] = 0;  // taken out
  return elements;
}

// The blocks summed element by element, every pair (a, b).
std::map<std::pair<int, int>, Mat3> reference_blocks(const Elements& elements) {
  std::map<std::pair<int, int>, Mat3> blocks;
  for (size_t e = 0; e < elements.lengths.size(); ++e) {
    const int* row = elements.neighbours.data() + e * static_cast<size_t>(elements.stride);
    for (int a = 0; a < elements.lengths[e]; ++a)
      for (int b = 0; b < elements.lengths[e]; ++b) {
        auto [entry, inserted] = blocks.try_emplace({row[a], row[b]}, Mat3::Zero());
        combine(elements.weights[e] * elements.vectors[e][static_cast<size_t>(a)] * elements.vectors[e][static_cast<size_t>(b)].transpose(),
                entry->second);
      }
  }
  return blocks;
}

// The index of block (row, column), -1 when it is outside the pattern.
int find_block(const BlockMatrix& matrix, int row, int column) {
  for (int k = matrix.row_start()[static_cast<size_t>(row)]; k < matrix.row_start()[static_cast<size_t>(row) + 1]; ++k)
    if (matrix.columns()[static_cast<size_t>(k)] == column) return k;
  return -1;
}

const BlockMatrix& assemble(ElementAssembly& assembly, const Elements& elements, Executor& executor) {
  if (!assembly.matches(elements.nodes, elements.stride, elements.lengths, elements.neighbours))
    assembly.build(elements.nodes, elements.stride, elements.lengths, elements.neighbours);
  for (size_t e = 0; e < elements.lengths.size(); ++e) {
    assembly.weight(static_cast<int>(e)) = elements.weights[e];
    for (int k = 0; k < elements.lengths[e]; ++k)
      Eigen::Map<Vec3>(assembly.gradients(static_cast<int>(e)) + 3 * assembly.local(static_cast<int>(e), k)) =
          elements.vectors[e][static_cast<size_t>(k)];
  }
  return assembly.assemble(executor, combine);
}

void expect_equals_reference(const BlockMatrix& matrix, const Elements& elements) {
  const auto reference = reference_blocks(elements);
  for (int row = 0; row < matrix.nodes(); ++row)
    for (int k = matrix.row_start()[static_cast<size_t>(row)]; k < matrix.row_start()[static_cast<size_t>(row) + 1]; ++k) {
      const auto found = reference.find({row, matrix.columns()[static_cast<size_t>(k)]});
      const Mat3 expected = found == reference.end() ? Mat3::Zero() : found->second;
      EXPECT_LE((matrix.blocks()[static_cast<size_t>(k)] - expected).cwiseAbs().maxCoeff(), 1e-13)
          << "block (" << row << ", " << matrix.columns()[static_cast<size_t>(k)] << ")";
    }
  for (const auto& [pair, block] : reference) EXPECT_GE(find_block(matrix, pair.first, pair.second), 0);
}

TEST(ElementGroups, ElementsWithTheSameNodesInAnyOrderShareAGroup) {
  const Elements elements = sample_elements();
  const ElementGroups groups = group_elements(elements.stride, elements.lengths, elements.neighbours);
  EXPECT_EQ(groups.count(), 4);
  EXPECT_EQ(groups.group_of, (std::vector<int>{0, 1, 0, 2, 0, 3, 1}));
  EXPECT_EQ(groups.member_of, (std::vector<int>{0, 0, 1, 0, 2, 0, 1}));
  EXPECT_EQ(std::vector<int>(groups.nodes.begin() + groups.node_start[3], groups.nodes.begin() + groups.node_start[4]),
            (std::vector<int>{5, 5, 6, 7}));
  // Element 2's row is {3, 1, 0, 2}: its entries sit at the sorted positions 3, 1, 0, 2.
  EXPECT_EQ(std::vector<int>(groups.local.begin() + 2 * elements.stride, groups.local.begin() + 2 * elements.stride + 4),
            (std::vector<int>{3, 1, 0, 2}));
}

TEST(ElementAssembly, EqualsTheElementByElementSum) {
  const Elements elements = sample_elements();
  ElementAssembly assembly;
  expect_equals_reference(assemble(assembly, elements, serial_executor()), elements);
  EXPECT_TRUE(assembly.pattern_rebuilt());
  // Off the diagonal the matrix is symmetric to the bit.
  const BlockMatrix& k = assembly.matrix();
  for (int row = 0; row < k.nodes(); ++row)
    for (int i = k.row_start()[static_cast<size_t>(row)]; i < k.row_start()[static_cast<size_t>(row) + 1]; ++i) {
      const int column = k.columns()[static_cast<size_t>(i)];
      if (column == row) continue;
      const Mat3 mirrored = k.blocks()[static_cast<size_t>(find_block(k, column, row))].transpose();
      EXPECT_EQ(0, std::memcmp(k.blocks()[static_cast<size_t>(i)].data(), mirrored.data(), sizeof(Mat3)));
    }
}

TEST(ElementAssembly, KeepsThePatternThroughEditsInsideItAndGrowsItForNewPairs) {
  Elements elements = sample_elements();
  ElementAssembly assembly;
  assemble(assembly, elements, serial_executor());
  const int blocks = assembly.matrix().block_count();
  // Element 3 drops node 11: its pairs are all in the pattern already.
  elements.lengths[3] = 3;
  expect_equals_reference(assemble(assembly, elements, serial_executor()), elements);
  EXPECT_FALSE(assembly.pattern_rebuilt());
  EXPECT_EQ(assembly.matrix().block_count(), blocks);
  // Element 6 reaches node 0: new pairs.
  elements.neighbours[6 * static_cast<size_t>(elements.stride)] = 0;
  expect_equals_reference(assemble(assembly, elements, serial_executor()), elements);
  EXPECT_TRUE(assembly.pattern_rebuilt());
}

TEST(ElementAssembly, HasTheSameBitsHoweverTheRowsAreSplitAndWhateverEditsLedThere) {
  Elements elements = sample_elements();
  ElementAssembly edited;
  assemble(edited, elements, serial_executor());
  elements.lengths[3] = 3;
  std::swap(elements.neighbours[1 * static_cast<size_t>(elements.stride)], elements.neighbours[1 * static_cast<size_t>(elements.stride) + 4]);
  std::swap(elements.vectors[1][0], elements.vectors[1][4]);
  const BlockMatrix& serial = assemble(edited, elements, serial_executor());
  EXPECT_FALSE(edited.pattern_rebuilt());
  ElementAssembly fresh;
  Shuffling shuffling(3);
  const BlockMatrix& shuffled = assemble(fresh, elements, shuffling);
  // The edited plan keeps the pairs of node 11, now zero; every block of the fresh one is there.
  EXPECT_GT(serial.block_count(), shuffled.block_count());
  for (int row = 0; row < shuffled.nodes(); ++row)
    for (int k = shuffled.row_start()[static_cast<size_t>(row)]; k < shuffled.row_start()[static_cast<size_t>(row) + 1]; ++k) {
      const int column = shuffled.columns()[static_cast<size_t>(k)];
      EXPECT_EQ(0, std::memcmp(shuffled.blocks()[static_cast<size_t>(k)].data(),
                               serial.blocks()[static_cast<size_t>(find_block(serial, row, column))].data(), sizeof(Mat3)));
    }
}

// Particle cells of a 3 x 2 x 2 grid of nodes (8 corners each, their points in random corner
// orders, 1 to 12 points a cell, one point of weight 0), with cut cells beside them: 5, 7 and
// 9 nodes, and 8 entries with a corner repeated (the fast path's length, not its usual shape).
Elements cell_elements() {
  std::mt19937 random(17);
  Elements elements;
  elements.nodes = 16;
  elements.stride = 9;
  auto corner = [](int i, int j, int k) { return i + 4 * j + 8 * k; };
  const int points[] = {8, 1, 12};
  for (int cell = 0; cell < 3; ++cell) {
    std::vector<int> corners;
    for (int k = 0; k < 2; ++k)
      for (int j = 0; j < 2; ++j)
        for (int i = 0; i < 2; ++i) corners.push_back(corner(cell + i, j, k));
    for (int p = 0; p < points[cell]; ++p) {
      std::shuffle(corners.begin(), corners.end(), random);
      elements.add(corners, random);
    }
  }
  elements.weights[3] = 0;
  elements.add({0, 1, 5, 4, 8}, random);
  elements.add({1, 2, 6, 5, 9, 10, 14}, random);
  elements.add({2, 3, 7, 6, 10, 11, 15, 14, 13}, random);
  elements.add({0, 1, 5, 4, 8, 9, 13, 13}, random);
  elements.add({13, 0, 1, 5, 4, 8, 9, 13}, random);
  elements.add({1, 2, 6, 5, 9, 10, 14}, random);
  return elements;
}

TEST(ElementAssembly, TheVectorisedSumsOfEightNodeGroupsHaveThePortableBits) {
  const Elements elements = cell_elements();
  ElementAssembly vectorised, portable;
  Shuffling shuffling(3);
  const BlockMatrix& fast = assemble(vectorised, elements, shuffling);
  set_element_assembly_vectorised(false);
  const BlockMatrix& slow = assemble(portable, elements, serial_executor());
  set_element_assembly_vectorised(true);
  std::printf("the 8-node sums vectorised on this CPU: %s\n", element_assembly_vectorised() ? "yes" : "no");
  expect_equals_reference(fast, elements);
  ASSERT_EQ(fast.block_count(), slow.block_count());
  EXPECT_EQ(0, std::memcmp(fast.blocks().data(), slow.blocks().data(), sizeof(Mat3) * fast.blocks().size()));
}

// Edits a few rows as a cut's re-selection does: a corner replaced by another node (often one
// of another cell, a new pair), a row shortened, its entries reordered, or made another row's
// node set (joining its group, which may move the group's first element).
// Edits one to three rows; returns the elements edited (some may have kept their rows).
std::vector<int> edit_rows(Elements& elements, std::mt19937& random) {
  const int count = static_cast<int>(elements.lengths.size());
  std::uniform_int_distribution<int> element(0, count - 1), node(0, elements.nodes - 1), kind(0, 3);
  std::vector<int> edited;
  for (int edits = 1 + element(random) % 3; edits > 0; --edits) {
    const int e = element(random);
    edited.push_back(e);
    int* row = elements.neighbours.data() + static_cast<size_t>(e) * elements.stride;
    int& length = elements.lengths[static_cast<size_t>(e)];
    switch (kind(random)) {
      case 0:
        if (length > 0) row[node(random) % length] = node(random);
        break;
      case 1:
        if (length > 1) --length;
        break;
      case 2:
        std::shuffle(row, row + length, random);
        break;
      default: {
        const int other = element(random);
        length = elements.lengths[static_cast<size_t>(other)];
        std::copy_n(elements.neighbours.data() + static_cast<size_t>(other) * elements.stride, elements.stride, row);
      }
    }
    elements.vectors[static_cast<size_t>(e)].resize(static_cast<size_t>(length), Vec3(0.25, -0.5, 0.75));
  }
  return edited;
}

TEST(ElementGroups, RegroupingEditedRowsGivesTheGroupsOfGroupingThemAfresh) {
  Elements elements = cell_elements();
  std::mt19937 random(5);
  ElementGroups groups = group_elements(elements.stride, elements.lengths, elements.neighbours);
  for (int round = 0; round < 200; ++round) {
    const Elements before = elements;
    edit_rows(elements, random);
    std::vector<int> changed;
    for (size_t e = 0; e < elements.lengths.size(); ++e)
      if (elements.lengths[e] != before.lengths[e] ||
          !std::equal(elements.neighbours.begin() + static_cast<std::ptrdiff_t>(e * elements.stride),
                      elements.neighbours.begin() + static_cast<std::ptrdiff_t>(e * elements.stride + elements.stride),
                      before.neighbours.begin() + static_cast<std::ptrdiff_t>(e * elements.stride)))
        changed.push_back(static_cast<int>(e));
    std::vector<int> previous_group;
    const ElementGroups edited = regroup_elements(groups, elements.stride, elements.lengths, elements.neighbours, changed, &previous_group);
    const ElementGroups fresh = group_elements(elements.stride, elements.lengths, elements.neighbours);
    ASSERT_EQ(edited.node_start, fresh.node_start) << "round " << round;
    ASSERT_EQ(edited.nodes, fresh.nodes) << "round " << round;
    ASSERT_EQ(edited.member_start, fresh.member_start) << "round " << round;
    ASSERT_EQ(edited.members, fresh.members) << "round " << round;
    ASSERT_EQ(edited.group_of, fresh.group_of) << "round " << round;
    ASSERT_EQ(edited.member_of, fresh.member_of) << "round " << round;
    ASSERT_EQ(edited.local, fresh.local) << "round " << round;
    // A group the previous grouping had, by its nodes; a new one nowhere in it.
    ASSERT_EQ(static_cast<int>(previous_group.size()), fresh.count());
    for (int g = 0; g < fresh.count(); ++g) {
      const std::vector<int> nodes(fresh.nodes.begin() + fresh.node_start[static_cast<size_t>(g)],
                                   fresh.nodes.begin() + fresh.node_start[static_cast<size_t>(g) + 1]);
      bool had = false;
      for (int p = 0; p < groups.count(); ++p)
        had = had || std::vector<int>(groups.nodes.begin() + groups.node_start[static_cast<size_t>(p)],
                                      groups.nodes.begin() + groups.node_start[static_cast<size_t>(p) + 1]) == nodes;
      const int p = previous_group[static_cast<size_t>(g)];
      if (!had) {
        EXPECT_EQ(p, -1);
        continue;
      }
      ASSERT_GE(p, 0);
      EXPECT_EQ(std::vector<int>(groups.nodes.begin() + groups.node_start[static_cast<size_t>(p)],
                                 groups.nodes.begin() + groups.node_start[static_cast<size_t>(p) + 1]),
                nodes);
    }
    groups = edited;
  }
}

TEST(ElementAssembly, APlanEditedCutByCutHasTheBitsOfOneBuiltForTheLastRows) {
  Elements elements = cell_elements();
  std::mt19937 random(11);
  ElementAssembly edited, listed;
  assemble(edited, elements, serial_executor());
  assemble(listed, elements, serial_executor());
  int grown = 0;
  for (int round = 0; round < 100; ++round) {
    std::vector<int> changed = edit_rows(elements, random);
    const int blocks = edited.matrix().block_count();
    const BlockMatrix& by_edits = assemble(edited, elements, serial_executor());
    // The same edits told by their list (with two elements whose rows did not change), as the
    // EFG model tells them: no row compared, the same plan.
    changed.push_back(static_cast<int>(random() % elements.lengths.size()));
    changed.push_back(static_cast<int>(random() % elements.lengths.size()));
    std::sort(changed.begin(), changed.end());
    changed.erase(std::unique(changed.begin(), changed.end()), changed.end());
    listed.build(elements.nodes, elements.stride, elements.lengths, elements.neighbours, &changed);
    ASSERT_TRUE(listed.matches(elements.nodes, elements.stride, elements.lengths, elements.neighbours));
    const BlockMatrix& by_list = assemble(listed, elements, serial_executor());
    ASSERT_EQ(by_list.row_start(), by_edits.row_start()) << "round " << round;
    ASSERT_EQ(by_list.columns(), by_edits.columns()) << "round " << round;
    for (int k = 0; k < by_edits.block_count(); ++k)
      ASSERT_EQ(0, std::memcmp(by_list.blocks()[static_cast<size_t>(k)].data(), by_edits.blocks()[static_cast<size_t>(k)].data(),
                               sizeof(Mat3)))
          << "round " << round << ", block " << k;
    grown += edited.pattern_rebuilt() ? 1 : 0;
    EXPECT_GE(by_edits.block_count(), blocks);  // kept, or grown by new pairs
    expect_equals_reference(by_edits, elements);
    ElementAssembly fresh;
    Shuffling shuffling(3);
    const BlockMatrix& built = assemble(fresh, elements, shuffling);
    for (int row = 0; row < by_edits.nodes(); ++row)
      for (int k = by_edits.row_start()[static_cast<size_t>(row)]; k < by_edits.row_start()[static_cast<size_t>(row) + 1]; ++k) {
        const int at = find_block(built, row, by_edits.columns()[static_cast<size_t>(k)]);
        const Mat3 expected = at < 0 ? Mat3::Zero() : built.blocks()[static_cast<size_t>(at)];
        ASSERT_EQ(0, std::memcmp(by_edits.blocks()[static_cast<size_t>(k)].data(), expected.data(), sizeof(Mat3)))
            << "round " << round << ", block (" << row << ", " << by_edits.columns()[static_cast<size_t>(k)] << ")";
      }
  }
  EXPECT_GT(grown, 0);  // some edits coupled new pairs
}

}  // namespace
}  // namespace incise::physics
