// The pattern and scatter plan for assembling a matrix of 3x3 blocks from elements whose node
// lists change only with the topology (a cut): built once per topology, then refilled every
// step (the current corotated stiffness K(x), physics/efg/efg_current_stiffness.cpp).
//
// A refill is parallel over block rows: each row is summed by one thread, its contributions in
// increasing element order, so the blocks do not depend on the thread count (like
// BlockSystem's product). Each element's block (a, b) is computed by the owner of row a, so
// nothing is shared between threads and no per-thread copy of the matrix is needed.
#pragma once

#include "physics/core/executor.hpp"
#include "physics/solve/block_matrix.hpp"

#include <span>
#include <vector>

namespace incise::physics {

class ElementAssembly {
 public:
  // True when the plan was built for exactly these rows: element e's nodes are
  // neighbours[e * stride + k], k < lengths[e].
  bool matches(int nodes, int stride, const std::vector<int>& lengths, const std::vector<int>& neighbours) const;
  // Builds the plan: the pattern where every pair of an element's nodes couples. For rows that
  // changed since the last build (a cut) whose pairs are all in the pattern already, only their
  // block indices and the incidence lists are redone: blocks no row uses any more stay, zero.
  void build(int nodes, int stride, const std::vector<int>& lengths, const std::vector<int>& neighbours);

  // Refills the matrix: block (row, column) = sum over the elements e holding both, in element
  // order, of block(e, a, b, out) (out += the element's block of local nodes a, b). Rows on
  // `executor`'s threads; the result does not depend on their count.
  template <typename ElementBlock>
  const BlockMatrix& assemble(Executor& executor, const ElementBlock& block);

  const BlockMatrix& matrix() const { return matrix_; }

 private:
  int stride_ = 0;
  std::vector<int> lengths_, neighbours_;  // the rows the plan was built for
  BlockMatrix matrix_;
  // Per node, the entries e * stride + a of the elements that hold it as local node a, in
  // increasing order.
  std::vector<int> incidence_start_, incidence_;
  // Per element entry e * stride^2 + a * stride + b: the index of block (node a, node b).
  std::vector<int> block_index_;
};

template <typename ElementBlock>
const BlockMatrix& ElementAssembly::assemble(Executor& executor, const ElementBlock& block) {
  Mat3* blocks = matrix_.mutable_blocks();
  const std::vector<int>& row_start = matrix_.row_start();
  constexpr int rows_per_thread = 64;
  executor.parallel_for(matrix_.nodes(), [&](int begin, int end) {
    for (int row = begin; row < end; ++row) {
      for (int k = row_start[static_cast<size_t>(row)]; k < row_start[static_cast<size_t>(row) + 1]; ++k) blocks[k].setZero();
      for (int i = incidence_start_[static_cast<size_t>(row)]; i < incidence_start_[static_cast<size_t>(row) + 1]; ++i) {
        const int entry = incidence_[static_cast<size_t>(i)];
        const int e = entry / stride_, a = entry % stride_;
        const int length = lengths_[static_cast<size_t>(e)];
        const int* index = block_index_.data() + (static_cast<size_t>(e) * stride_ + a) * stride_;
        for (int b = 0; b < length; ++b) block(e, a, b, blocks[index[b]]);
      }
    }
  }, rows_per_thread);
  return matrix_;
}

}  // namespace incise::physics
