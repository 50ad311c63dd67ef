// The pattern and plan for assembling, in 3x3 blocks, a stiffness whose element blocks are
// Gram-type: element e with weight w_e and one vector h_k per node k adds
//   block (a, b) = C(w_e h_a h_b^T)
// for a linear C with C(S^T) = C(S)^T (the corotated EFG's V (lambda h_a h_b^T + mu h_b h_a^T +
// mu (h_a . h_b) I), physics/efg/efg_current_stiffness.cpp). Built once per topology (a cut
// rebuilds it), refilled every step.
//
// Elements with the same node set (element_groups.hpp: the 8 integration points of an EFG
// particle cell) are summed before the scatter: per group and node pair, S_ab = sum_e w_e h_a
// h_b^T in registers (for a group of 8 nodes with AVX2 where the CPU has it, four columns to a
// lane set, the portable loop's bits); the S of every group on a block are summed in the row's
// scratch and C, being linear, turns the sum once per block. Only the upper blocks (column >=
// row) are computed, the lower ones copied as their mirror's transpose, so the matrix is exactly
// symmetric off the diagonal.
//
// A refill is parallel over block rows: each upper block is summed by its row's thread, its
// groups in group order and each group's elements in element order, and written once; each
// lower block is copied by its row's thread, in the same pass where its mirror lies in the
// thread's range (done before it), after the pass otherwise. Nothing depends on the thread count.
//
// The pattern is kept across cuts while it covers every group's node pairs (blocks no group
// uses any more stay, refilled with zero); a cut that couples a new pair grows it by the new
// pairs. A plan for rows that differ from the last ones in a few elements (a cut re-selects a
// few hundred neighbourhoods of 20k) is edited, not rebuilt (element_assembly_edit.cpp): only
// the changed rows are grouped afresh (regroup_elements, the same groups as group_elements)
// and only new node sets' pairs looked up in the pattern. A first plan, or one for rows that
// changed throughout, is built from the groups (a few thousand at 20k EFG elements, not every
// element's 64 pairs).
#pragma once

#include "physics/core/executor.hpp"
#include "physics/solve/block_matrix.hpp"
#include "physics/solve/element_groups.hpp"

#include <algorithm>
#include <span>
#include <utility>
#include <vector>

namespace incise::physics {

// Whether the sums of 8-node groups run their AVX2 kernel on this CPU (its bits are the
// portable loop's).
bool element_assembly_vectorised();
// Tests: force the portable loop (false) or the CPU's best (true).
void set_element_assembly_vectorised(bool allowed);

class ElementAssembly {
 public:
  // True when the plan was built for exactly these rows: element e's nodes are
  // neighbours[e * stride + k], k < lengths[e].
  bool matches(int nodes, int stride, const std::vector<int>& lengths, const std::vector<int>& neighbours) const;
  // Builds the plan for these rows (see the file comment on the pattern). `changed`, when
  // given: the elements whose rows may differ from the last plan's (increasing, no repeats; any
  // element whose row did change must be in it), which spares the edit its comparison of every
  // row; the plan is the same.
  void build(int nodes, int stride, const std::vector<int>& lengths, const std::vector<int>& neighbours,
             const std::vector<int>* changed = nullptr);

  // Element e's vectors, to fill before assemble: entry k's h (3 doubles) at gradients(e) +
  // 3 local(e, k). Every element's vectors are in its group's node order.
  double* gradients(int element) {
    return gradients_.data() + gradient_offset_[static_cast<size_t>(groups_.group_of[static_cast<size_t>(element)])] +
           static_cast<size_t>(3 * groups_.length(groups_.group_of[static_cast<size_t>(element)])) *
               static_cast<size_t>(groups_.member_of[static_cast<size_t>(element)]);
  }
  int local(int element, int k) const { return groups_.local[static_cast<size_t>(element) * stride_ + static_cast<size_t>(k)]; }
  // Element e's weight, to set before assemble (an element of weight 0 adds nothing); kept in
  // its group's member order, beside its vectors.
  double& weight(int element) {
    return weights_[static_cast<size_t>(groups_.member_start[static_cast<size_t>(groups_.group_of[static_cast<size_t>(element)])] +
                                        groups_.member_of[static_cast<size_t>(element)])];
  }

  // Refills the matrix from the vectors and the weights: block (row, column) = sum over the
  // elements e holding both of C(w_e h h^T), `combine(S, out)` adding C(S) to out. Rows on
  // `executor`'s threads; the result does not depend on their count.
  template <typename Combine>
  const BlockMatrix& assemble(Executor& executor, const Combine& combine);

  const BlockMatrix& matrix() const { return matrix_; }
  const ElementGroups& groups() const { return groups_; }
  // Whether the last build had to lay a new pattern (false: it re-indexed the old one).
  bool pattern_rebuilt() const { return pattern_rebuilt_; }

 private:
  // One group's node `a` at a block row: its pairs (a, b >= a) are blocks pair_index_[pairs + b - a].
  struct Incidence {
    int group, a, pairs;
  };
  // The plan for rows edited in a few elements, from the last plan; false (nothing done) when
  // there is none to edit or the rows changed throughout.
  bool edit(int nodes, int stride, const std::vector<int>& lengths, const std::vector<int>& neighbours,
            const std::vector<int>* changed);
  // Adds the (row, column) blocks `missing` names (not in the pattern, both of a pair's
  // mirrors); returns per old block its index in the grown pattern.
  std::vector<int> grow_pattern(std::vector<std::pair<int, int>> missing);
  void size_groups();  // longest_, pair_start_, gradient_offset_ and the vectors' room, from groups_
  bool index_pairs();  // false when a group's pair is outside matrix_'s pattern
  void index_mirrors();
  void list_incidences();
  // The row's upper blocks = sum over its incidences of S_ab (sum_pairs), S_ab + S_ab^T where
  // the group repeats the row's node at b. `scratch`: 9 longest_ + padding doubles.
  // sums[k - upper_start_[row]] is block k's sum.
  void sum_row(int row, double* scratch, Mat3* sums) const;
  // sums (3 x 3(L - a), row-major with `pitch` doubles a row; returned) = sum over the group's
  // elements of w_e h_a h_b^T for b >= a, block b - a in columns 3(b - a) .. 3(b - a) + 2.
  int sum_pairs(const Incidence& incidence, double* sums) const;
  // The vectorised sums of an 8-node group may read (and sum, unused) up to 3 doubles past a
  // row: the gradients and the scratch end in this many spare doubles.
  static constexpr int padding = 4;

  int stride_ = 0;
  std::vector<int> lengths_, neighbours_;  // the rows the plan was built for
  ElementGroups groups_;
  BlockMatrix matrix_;
  bool pattern_rebuilt_ = false;
  int longest_ = 0;                     // the longest group
  std::vector<int> pair_start_;         // per group: its first pair in pair_index_
  std::vector<int> pair_index_;         // per group, a, b >= a: the block (node a, node b)
  std::vector<int> mirror_;             // per block: its transpose's index
  std::vector<int> upper_start_;        // per row: its first block of column >= row
  int widest_ = 0;                      // the most upper blocks in a row
  std::vector<int> range_begin_;        // per row: the first row of its range in the last refill
  std::vector<int> incidence_start_;    // per row
  std::vector<Incidence> incidence_;    // per row, in group order
  std::vector<size_t> gradient_offset_; // per group: its elements' vectors, one after another
  std::vector<double> gradients_;
  std::vector<double> weights_;         // per group, per member
};

template <typename Combine>
const BlockMatrix& ElementAssembly::assemble(Executor& executor, const Combine& combine) {
  Mat3* blocks = matrix_.mutable_blocks();
  const std::vector<int>& row_start = matrix_.row_start();
  const std::vector<int>& columns = matrix_.columns();
  constexpr int rows_per_thread = 64;
  executor.parallel_for(matrix_.nodes(), [&](int begin, int end) {
    std::vector<double> scratch(static_cast<size_t>(9 * longest_ + padding));
    std::vector<Mat3> sums(static_cast<size_t>(widest_));
    for (int row = begin; row < end; ++row) {
      // The row's upper blocks are summed here (S, each pair's sums) and turned by C once each.
      sum_row(row, scratch.data(), sums.data());
      const int first = upper_start_[static_cast<size_t>(row)];
      for (int k = first; k < row_start[static_cast<size_t>(row) + 1]; ++k) {
        Mat3 out = Mat3::Zero();
        combine(sums[static_cast<size_t>(k - first)], out);
        blocks[k] = out;
      }
      // Its lower blocks are their mirrors' transposes, here those of this range's rows (done),
      // the others' after every range (below): each block written once, by one thread, in
      // order along the row.
      range_begin_[static_cast<size_t>(row)] = begin;
      for (int k = row_start[static_cast<size_t>(row)]; k < first; ++k)
        if (columns[static_cast<size_t>(k)] >= begin) blocks[k] = blocks[mirror_[static_cast<size_t>(k)]].transpose();
    }
  }, rows_per_thread);
  executor.parallel_for(matrix_.nodes(), [&](int begin, int end) {
    for (int row = begin; row < end; ++row)
      for (int k = row_start[static_cast<size_t>(row)];
           k < row_start[static_cast<size_t>(row) + 1] && columns[static_cast<size_t>(k)] < range_begin_[static_cast<size_t>(row)]; ++k)
        blocks[k] = blocks[mirror_[static_cast<size_t>(k)]].transpose();
  }, 4 * rows_per_thread);
  return matrix_;
}

}  // namespace incise::physics
