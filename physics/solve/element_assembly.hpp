// The pattern and plan for assembling, in 3x3 blocks, a stiffness whose element blocks are
// Gram-type: element e with weight w_e and one vector h_k per node k adds
//   block (a, b) = C(w_e h_a h_b^T)
// for a linear C with C(S^T) = C(S)^T (the corotated EFG's V (lambda h_a h_b^T + mu h_b h_a^T +
// mu (h_a . h_b) I), physics/efg/efg_current_stiffness.cpp). Built once per topology (a cut
// rebuilds it), refilled every step.
//
// Elements with the same node set (element_groups.hpp: the 8 integration points of an EFG
// particle cell) are summed before the scatter: per group and node pair, S_ab = sum_e w_e h_a
// h_b^T in registers, then one block C(S_ab) added; only the upper blocks (column >= row) are
// computed, the lower ones copied as their mirror's transpose, so the matrix is exactly
// symmetric off the diagonal.
//
// A refill is parallel over block rows: each upper block is summed by its row's thread, its
// groups in group order and each group's elements in element order; then each lower block is
// copied by its row's thread. Nothing depends on the thread count.
//
// The pattern is kept across cuts while it covers every group's node pairs (blocks no group
// uses any more stay, refilled with zero); a cut that couples a new pair rebuilds it, from the
// groups (a few thousand at 20k EFG elements, not every element's 64 pairs).
#pragma once

#include "physics/core/executor.hpp"
#include "physics/solve/block_matrix.hpp"
#include "physics/solve/element_groups.hpp"

#include <algorithm>
#include <span>
#include <vector>

namespace incise::physics {

class ElementAssembly {
 public:
  // True when the plan was built for exactly these rows: element e's nodes are
  // neighbours[e * stride + k], k < lengths[e].
  bool matches(int nodes, int stride, const std::vector<int>& lengths, const std::vector<int>& neighbours) const;
  // Builds the plan for these rows (see the file comment on the pattern).
  void build(int nodes, int stride, const std::vector<int>& lengths, const std::vector<int>& neighbours);

  // Element e's vectors, to fill before assemble: entry k's h (3 doubles) at gradients(e) +
  // 3 local(e, k). Every element's vectors are in its group's node order.
  double* gradients(int element) {
    return gradients_.data() + gradient_offset_[static_cast<size_t>(groups_.group_of[static_cast<size_t>(element)])] +
           static_cast<size_t>(3 * groups_.length(groups_.group_of[static_cast<size_t>(element)])) *
               static_cast<size_t>(groups_.member_of[static_cast<size_t>(element)]);
  }
  int local(int element, int k) const { return groups_.local[static_cast<size_t>(element) * stride_ + static_cast<size_t>(k)]; }

  // Refills the matrix from the vectors and the weights (one per element; an element of weight
  // 0 adds nothing): block (row, column) = sum over the elements e holding both of C(w_e h h^T),
  // `combine(S, out)` adding C(S) to out. Rows on `executor`'s threads; the result does not
  // depend on their count.
  template <typename Combine>
  const BlockMatrix& assemble(Executor& executor, std::span<const double> weights, const Combine& combine);

  const BlockMatrix& matrix() const { return matrix_; }
  const ElementGroups& groups() const { return groups_; }
  // Whether the last build had to lay a new pattern (false: it re-indexed the old one).
  bool pattern_rebuilt() const { return pattern_rebuilt_; }

 private:
  // One group's node `a` at a block row: its pairs (a, b >= a) are blocks pair_index_[pairs + b - a].
  struct Incidence {
    int group, a, pairs;
  };
  bool index_pairs();  // false when a group's pair is outside matrix_'s pattern
  void index_mirrors();
  void list_incidences();
  // sums (3 x 3(L - a), row-major) = sum over the group's elements of w_e h_a h_b^T for b >= a,
  // block b - a in columns 3(b - a) .. 3(b - a) + 2.
  void sum_pairs(const Incidence& incidence, std::span<const double> weights, double* sums) const;

  int stride_ = 0;
  std::vector<int> lengths_, neighbours_;  // the rows the plan was built for
  ElementGroups groups_;
  BlockMatrix matrix_;
  bool pattern_rebuilt_ = false;
  int longest_ = 0;                     // the longest group
  std::vector<int> pair_start_;         // per group: its first pair in pair_index_
  std::vector<int> pair_index_;         // per group, a, b >= a: the block (node a, node b)
  std::vector<int> mirror_;             // per block: its transpose's index
  std::vector<int> incidence_start_;    // per row
  std::vector<Incidence> incidence_;    // per row, in group order
  std::vector<size_t> gradient_offset_; // per group: its elements' vectors, one after another
  std::vector<double> gradients_;
};

template <typename Combine>
const BlockMatrix& ElementAssembly::assemble(Executor& executor, std::span<const double> weights, const Combine& combine) {
  Mat3* blocks = matrix_.mutable_blocks();
  const std::vector<int>& row_start = matrix_.row_start();
  const std::vector<int>& columns = matrix_.columns();
  constexpr int rows_per_thread = 64;
  executor.parallel_for(matrix_.nodes(), [&](int begin, int end) {
    std::vector<double> sums(static_cast<size_t>(9 * longest_));
    for (int row = begin; row < end; ++row) {
      const auto first = columns.begin() + row_start[static_cast<size_t>(row)];
      const auto last = columns.begin() + row_start[static_cast<size_t>(row) + 1];
      for (auto k = std::lower_bound(first, last, row); k != last; ++k) blocks[k - columns.begin()].setZero();
      for (int i = incidence_start_[static_cast<size_t>(row)]; i < incidence_start_[static_cast<size_t>(row) + 1]; ++i) {
        const Incidence& incidence = incidence_[static_cast<size_t>(i)];
        sum_pairs(incidence, weights, sums.data());
        const int* nodes = groups_.nodes.data() + groups_.node_start[static_cast<size_t>(incidence.group)];
        const int length = groups_.length(incidence.group);
        const int width = 3 * (length - incidence.a);
        for (int b = incidence.a; b < length; ++b) {
          Mat3 sum;
          for (int c = 0; c < 3; ++c)
            for (int d = 0; d < 3; ++d) sum(c, d) = sums[static_cast<size_t>(c * width + 3 * (b - incidence.a) + d)];
          Mat3& out = blocks[pair_index_[static_cast<size_t>(incidence.pairs + b - incidence.a)]];
          combine(sum, out);
          // A node repeated in the group: its pair (b, a) falls on the same diagonal block.
          if (b != incidence.a && nodes[b] == nodes[incidence.a]) {
            Mat3 mirrored = Mat3::Zero();
            combine(sum, mirrored);
            out += mirrored.transpose();
          }
        }
      }
    }
  }, rows_per_thread);
  executor.parallel_for(matrix_.nodes(), [&](int begin, int end) {
    for (int row = begin; row < end; ++row)
      for (int k = row_start[static_cast<size_t>(row)]; k < row_start[static_cast<size_t>(row) + 1] && columns[static_cast<size_t>(k)] < row; ++k)
        blocks[k] = blocks[mirror_[static_cast<size_t>(k)]].transpose();
  }, 4 * rows_per_thread);
  return matrix_;
}

}  // namespace incise::physics
